// RANSAC line detector (the peer baseline): a synthetic bright line in noise, surface
// removal, target, determinism, and bad input that must give "not found".
#include "tracking/ransac_line_detector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>

#include "tests/test_util/constants.h"
#include "tests/test_util/synthetic_volume.h"

namespace echoservo::tracking {
namespace {

using testing::kDeg;

using testing::Synthetic;

void AddNoise(imaging::Volume& v, std::uint32_t seed, int lo, int span) {
  std::uint32_t state = seed;
  for (auto& x : v.voxels()) {
    state = state * 1664525u + 1013904223u;
    x = static_cast<std::uint8_t>(lo + (state >> 24) % span);
  }
}

// A bright Gaussian-profile line from p0 (where it enters, at the x = 0 face) to p0 + tip_s·dir;
// `saturated`: flat 250 within 0.8 mm of the axis instead (a saturated catheter echo).
void AddLine(imaging::Volume& v, const Eigen::Vector3d& p0, const Eigen::Vector3d& dir,
             double tip_s, bool saturated = false) {
  const int n = v.dims().x();
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d p = v.IndexToPhysical(Eigen::Vector3d(i, j, k));
        const double s = (p - p0).dot(dir);
        const double r = (p - p0 - s * dir).norm();
        if (s <= tip_s && r < 1.5) {
          const double val =
              saturated ? (r < 0.8 ? 250.0 : 0.0) : 250.0 * std::exp(-r * r / (2 * 0.4 * 0.4));
          v.at(i, j, k) = static_cast<std::uint8_t>(std::max<double>(v.at(i, j, k), val));
        }
      }
}

const Eigen::Vector3d kP0(0.0, 24.3, 20.7);
const Eigen::Vector3d kDir = Eigen::Vector3d(1.0, 0.15, 0.25).normalized();
constexpr double kTipS = 30.0;

TEST(RansacLineDetector, FindsASyntheticBrightLineInNoise) {
  auto v = Synthetic(96, 0.5, 0);
  AddNoise(v, 7, 40, 40);
  AddLine(v, kP0, kDir, kTipS);
  const auto d = RansacLineDetector().Detect(v);
  ASSERT_TRUE(d.found);
  const double angle = AngleBetweenLines(d.axis, Line3{kP0, kDir}) / kDeg;
  const double tip = (d.tip_mm - (kP0 + kTipS * kDir)).norm();
  EXPECT_LT(angle, 1.0);
  EXPECT_LT(PointToLineDistance(d.axis, kP0 + kTipS * kDir), 0.3);
  EXPECT_LT(tip, 1.5);  // the inlier extreme: the last voxel above the threshold
  EXPECT_GT(d.axis.direction.dot(kDir), 0.0);  // oriented towards the tip
  EXPECT_GT(d.confidence, 0.5);
  EXPECT_GT(d.line_length_mm, 20.0);
  EXPECT_FALSE(d.tracked);
}

TEST(RansacLineDetector, IgnoresABrightSurfaceAndFindsTheTargetAhead) {
  auto v = Synthetic(96, 0.5, 0);
  AddNoise(v, 11, 40, 40);
  AddLine(v, kP0, kDir, kTipS, true);
  // A bright plane (a tank floor) as bright as the line and far larger, and a tissue wall
  // ahead of the tip.
  for (int j = 0; j < 96; ++j)
    for (int i = 0; i < 96; ++i) v.at(i, j, 90) = 250;
  const Eigen::Vector3d wall = kP0 + (kTipS + 8.0) * kDir;
  for (int k = 0; k < 96; ++k)
    for (int j = 0; j < 96; ++j)
      for (int i = 0; i < 96; ++i) {
        const double s = (v.IndexToPhysical(Eigen::Vector3d(i, j, k)) - wall).dot(kDir);
        if (s >= 0 && s < 2.0) v.at(i, j, k) = std::max<std::uint8_t>(v.at(i, j, k), 160);
      }
  const auto d = RansacLineDetector().Detect(v);
  ASSERT_TRUE(d.found);
  EXPECT_LT(AngleBetweenLines(d.axis, Line3{kP0, kDir}) / kDeg, 1.0);
  ASSERT_TRUE(d.target_found);
  EXPECT_LT((d.target_mm - wall).norm(), 1.5);
}

TEST(RansacLineDetector, IsDeterministic) {
  auto v = Synthetic(64, 0.5, 0);
  AddNoise(v, 3, 30, 60);
  AddLine(v, Eigen::Vector3d(0.0, 15.0, 12.0), Eigen::Vector3d(1.0, 0.2, 0.1).normalized(), 20.0);
  const RansacLineDetector detector;
  const auto a = detector.Detect(v), b = detector.Detect(v);
  ASSERT_EQ(a.found, b.found);
  EXPECT_EQ(a.axis.point, b.axis.point);
  EXPECT_EQ(a.axis.direction, b.axis.direction);
  EXPECT_EQ(a.tip_mm, b.tip_mm);
}

TEST(RansacLineDetector, BadInputIsNotFound) {
  const RansacLineDetector detector;
  EXPECT_FALSE(detector.Detect(Synthetic(64, 0.5, 0)).found) << "all zero";
  EXPECT_FALSE(detector.Detect(Synthetic(64, 0.5, 128)).found) << "constant";
  EXPECT_FALSE(detector.Detect(Synthetic(64, 0.5, 255)).found) << "saturated";
  EXPECT_FALSE(detector.Detect(Synthetic(7, 0.5, 200)).found) << "tiny";
  auto noise = Synthetic(80, 0.5, 0);
  AddNoise(noise, 12345, 60, 60);
  EXPECT_FALSE(detector.Detect(noise).found) << "uniform noise";
  auto dot = Synthetic(64, 0.5, 10);
  dot.at(30, 30, 30) = 255;
  EXPECT_FALSE(detector.Detect(dot).found) << "one bright voxel";
}

TEST(RansacLineDetector, RejectsBadOptions) {
  auto bad = [](auto mutate) {
    RansacLineDetectorOptions o;
    mutate(o);
    EXPECT_THROW(RansacLineDetector{o}, std::invalid_argument);
  };
  bad([](auto& o) { o.threshold_quantile = 1.0; });
  bad([](auto& o) { o.inlier_radius_mm = 0.0; });
  bad([](auto& o) { o.iterations = 0; });
  bad([](auto& o) { o.max_sample_separation_mm = o.min_sample_separation_mm; });
  bad([](auto& o) { o.min_inliers = 1; });
  bad([](auto& o) { o.target_search_mm = o.target_start_mm; });
  bad([](auto& o) { o.shell_penalty = std::nan(""); });
  EXPECT_NO_THROW(RansacLineDetector{});
}

}  // namespace
}  // namespace echoservo::tracking
