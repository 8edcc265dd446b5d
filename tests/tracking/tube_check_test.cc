// Tube-vs-surface test of tracking/tube_check.h on synthetic shapes.
#include "tracking/tube_check.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "tests/test_util/expect_error.h"

namespace echoservo::tracking {
namespace {

// 0.5 mm voxels, 40 mm cube at z ∈ [40, 80] mm (apex at the origin: beams along ≈ +z, known
// unless `known_beams` is false); `value(p)` gives the display value at a point.
imaging::Volume Make(const std::function<double(const Eigen::Vector3d&)>& value,
                     bool known_beams = true) {
  imaging::VolumeGeometry g;
  g.dims = Eigen::Vector3i(81, 81, 81);
  g.spacing_mm = Eigen::Vector3d::Constant(0.5);
  g.origin_mm = Eigen::Vector3d(-20, -20, 40);
  auto v = imaging::Volume::Create(g);
  if (known_beams) v.set_image_to_probe(Eigen::Isometry3d::Identity());
  for (int k = 0; k < 81; ++k)
    for (int j = 0; j < 81; ++j)
      for (int i = 0; i < 81; ++i)
        v.at(i, j, k) = static_cast<std::uint8_t>(
            std::clamp(value(v.IndexToPhysical(Eigen::Vector3d(i, j, k))), 0.0, 255.0));
  return v;
}

const Line3 kAxis{Eigen::Vector3d(0, 0, 60), Eigen::Vector3d::UnitX()};

double Tube(const Eigen::Vector3d& p) {
  const double r = std::hypot(p.y(), p.z() - 60);
  return r < 1.0 ? 250.0 : 20.0;
}

TEST(Tubularity, ACatheterInWaterIsATube) {
  const auto v = Make(Tube);
  EXPECT_GT(Tubularity(v, kAxis, -15, 15, 50, {}), 0.95);
}

TEST(Tubularity, ACometTailBehindTheCatheterIsIgnored) {
  // Reverberation below the catheter, along the beam (+z), 1–8 mm deep.
  const auto v = Make([](const Eigen::Vector3d& p) {
    const double dz = p.z() - 60;
    if (std::abs(p.y()) < 1.0 && dz > 1 && dz < 8) return 200.0;
    return Tube(p);
  });
  EXPECT_GT(Tubularity(v, kAxis, -15, 15, 50, {}), 0.95);
}

// Reverberation copies of the catheter every 2.5 mm along the beam, seen in the cross-section:
// a ribbon in ONE direction (the beam's projection ⟂ the axis, here 53° from +z) whose copies
// decay by `decay_db_per_copy` each (6 dB: 31 display levels over 50 dB).
double Ribbon(const Eigen::Vector3d& p, double decay_db_per_copy) {
  const Eigen::Vector3d e = Eigen::Vector3d(0, -0.8, 0.6);  // the beam's projection ⟂ the axis
  const Eigen::Vector3d q(0, p.y(), p.z() - 60);
  double best = Tube(p);
  for (int k = 1; k <= 4; ++k) {
    const double r = (q - 2.5 * k * e).norm();
    if (r < 0.8) best = std::max(best, 250.0 - k * decay_db_per_copy * 255.0 / 50.0);
  }
  return best;
}

TEST(Tubularity, UnknownBeamsADecayingRibbonIsReverberation) {
  // The volume does not know its beams: the cross-section shows the ribbon's direction, and
  // its decay says it is reverberation.
  const auto v = Make([](const Eigen::Vector3d& p) { return Ribbon(p, 6.0); }, false);
  EXPECT_GT(Tubularity(v, kAxis, -15, 15, 50, {}), 0.9);
  // Known beams that explain the ribbon (along e, from far above): the same answer.
  EXPECT_GT(
      Tubularity(v, kAxis, -15, 15, 50, {}, BeamGeometry::Parallel(Eigen::Vector3d(0, -0.8, 0.6))),
      0.9);
  // Told that no ribbon was found over this range (the caller looked), no sector is skipped:
  // the ribbon's copies (6 dB down each) count against the tube (0.75 here, against > 0.9).
  EXPECT_LT(Tubularity(v, kAxis, -15, 15, 50, {}, BeamGeometry{}, false), 0.85);
}

TEST(Tubularity, UnknownBeamsAUniformHalfPlaneIsNotARibbon) {
  // A plate ending at the line (no decay away from it), in the same direction as the ribbon.
  const auto v = Make(
      [](const Eigen::Vector3d& p) {
        const Eigen::Vector3d e(0, -0.8, 0.6), q(0, p.y(), p.z() - 60);
        const double along = q.dot(e), across = (q - along * e).norm();
        return along > 0 && across < 0.5 ? 250.0 : Tube(p);
      },
      false);
  EXPECT_LT(Tubularity(v, kAxis, -15, 15, 50, {}), 0.1);
  // And a plane through the line, and a surface beside it, unknown beams too.
  const auto plane = Make(
      [](const Eigen::Vector3d& p) { return std::abs(p.z() - 60) < 0.5 ? 250.0 : 20.0; }, false);
  EXPECT_LT(Tubularity(plane, kAxis, -15, 15, 50, {}), 0.1);
}

TEST(Tubularity, ALineWithinAPlaneIsNotATube) {
  // A bright floor (1 mm thick, ⟂ the beam) containing the line.
  const auto v =
      Make([](const Eigen::Vector3d& p) { return std::abs(p.z() - 60) < 0.5 ? 250.0 : 20.0; });
  EXPECT_LT(Tubularity(v, kAxis, -15, 15, 50, {}), 0.1);
}

TEST(Tubularity, ThePlaneEdgeIsNotATubeEither) {
  const auto v = Make([](const Eigen::Vector3d& p) {
    return std::abs(p.z() - 60) < 0.5 && p.y() > 0 ? 250.0 : 20.0;
  });
  EXPECT_LT(Tubularity(v, kAxis, -15, 15, 50, {}), 0.1);
}

TEST(Tubularity, ACatheterBesideTissueSpeckleIsStillATube) {
  // Tissue 3 mm away at 30 dB below the catheter's echo (display 150 of 255 over 50 dB).
  const auto v = Make([](const Eigen::Vector3d& p) { return p.y() > 3.0 ? 100.0 : Tube(p); });
  EXPECT_GT(Tubularity(v, kAxis, -15, 15, 50, {}), 0.9);
}

TEST(Tubularity, OutsideTheVolumeIsZeroAndOptionsAreValidated) {
  const auto v = Make(Tube);
  EXPECT_EQ(
      Tubularity(v, Line3{Eigen::Vector3d(0, 0, 500), Eigen::Vector3d::UnitX()}, -5, 5, 50, {}),
      0.0);
  TubeCheckOptions o;
  o.ring_outer_mm = 2.0;  // inside the inner radius
  testing::ExpectContains(testing::InvalidArgumentMessage([&] { o.Validate(); }), "ring_outer_mm");
}

}  // namespace
}  // namespace echoservo::tracking
