// EM-to-image alignment (report/em_alignment.h) on synthetic runs with a known clock
// offset and rigid transform: recovered within tolerances derived from the image noise and
// the motion (Cramér-Rao-style standard deviations × a margin); the refusals (too few
// samples, a tip moving along a line, inches read as mm, an EM sensor that did not follow)
// say why.
#include "report/em_alignment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "tests/test_util/expect_error.h"
#include "tests/test_util/synthetic_run.h"

namespace echoservo {
namespace {

using report::AlignEmToImage;
using report::EmAlignment;
using report::EmAlignmentOptions;
using report::PointSeries;
using testing::ExpectContains;
using testing::InvalidArgumentMessage;
using testing::SyntheticRun;

constexpr double kMargin = 4.0;  // tolerance = kMargin × the derived standard deviation

PointSeries EmSeries(const SyntheticRun& s, double scale = 1.0) {
  PointSeries p;
  for (const formats::EmSample& e : s.EmSamples()) {
    if (e.valid) p.Add(e.t_s, scale * e.position_mm);
  }
  return p;
}

PointSeries ImageTips(const SyntheticRun& s) {
  PointSeries p;
  for (const formats::TargetRecord& r : s.Targets()) {
    if (r.found) p.Add(r.acquired_s, r.tip_mm);
  }
  return p;
}

// Standard deviations the noise allows (isotropic σ per axis on N image tips): a point of
// the fitted transform at the centroid σ/√N per axis; the rotation about principal axis i
// σ / (√(s_j² + s_k²)·√N), s the tip's principal spreads, so the rotation angle's RMS is
// the root sum of the three; the clock offset σ / √(Σ|v_i|²), v the tip velocity at the
// image times.
struct DerivedSd {
  double position_mm, rotation_rad, offset_s;
};
DerivedSd Derive(const SyntheticRun& s, const EmAlignment& a) {
  const PointSeries tips = ImageTips(s);
  const double n = static_cast<double>(tips.size());
  const double sigma = s.image_noise_mm;
  const Eigen::Vector3d sp = a.spread_mm;
  double v2 = 0.0;
  for (double t : tips.t_s) {
    const double h = 1e-4;
    v2 += ((s.TipAt(t + h) - s.TipAt(t - h)) / (2 * h)).squaredNorm();
  }
  const double rotation =
      sigma / std::sqrt(n) *
      std::sqrt(1 / (sp[1] * sp[1] + sp[2] * sp[2]) + 1 / (sp[0] * sp[0] + sp[2] * sp[2]) +
                1 / (sp[0] * sp[0] + sp[1] * sp[1]));
  return {sigma / std::sqrt(n), rotation, sigma / std::sqrt(v2)};
}

double RotationErrorRad(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle();
}

// Largest distance between the two transforms' images of the tip positions (in EM frame).
double MappedErrorMm(const SyntheticRun& s, const Eigen::Isometry3d& est) {
  double worst = 0.0;
  for (const formats::EmSample& e : s.EmSamples()) {
    if (e.valid)
      worst = std::max(worst, (est * e.position_mm - s.em_to_image * e.position_mm).norm());
  }
  return worst;
}

TEST(EmAlignment, RecoversOffsetAndPoseWithinTheNoise) {
  SyntheticRun s;
  s.duration_s = 40.0;
  s.em_rate_hz = 40.0;
  s.amplitude_mm = {12.0, 10.0, 8.0};  // a registration sweep
  s.image_noise_mm = 0.3;
  s.em_dropout_every = 9;
  const EmAlignment a = AlignEmToImage(EmSeries(s), ImageTips(s));
  const DerivedSd sd = Derive(s, a);
  // The derived tolerances are tighter than the report needs (few ms, 0.5°, 0.3 mm).
  ASSERT_LT(kMargin * sd.offset_s, 0.003);
  ASSERT_LT(kMargin * sd.rotation_rad * 180 / std::numbers::pi, 0.5);
  // Linear interpolation of the EM track between samples h apart is off by up to
  // a_max·h²/8 on the pairs: a bias the pose absorbs, added to the tolerance.
  const double h = 1.0 / s.em_rate_hz;
  const double interpolation_mm = s.MaxAccelerationMmS2() * h * h / 8.0;
  EXPECT_NEAR(a.em_time_offset_s, s.em_clock_offset_s, kMargin * sd.offset_s + 2e-4)
      << "offset SD " << sd.offset_s;
  EXPECT_LT(RotationErrorRad(a.em_to_image, s.em_to_image), kMargin * sd.rotation_rad);
  EXPECT_LT(MappedErrorMm(s, a.em_to_image),
            kMargin * (std::sqrt(3.0) * sd.position_mm + sd.rotation_rad * 3.0 * a.spread_mm[0]) +
                interpolation_mm);
  // The residual is the image noise: √3·σ per pair (3 axes), less the fitted parameters.
  EXPECT_NEAR(a.residual_rms_mm, std::sqrt(3.0) * s.image_noise_mm, 0.1 * s.image_noise_mm);
  EXPECT_GT(a.pairs, ImageTips(s).size() * 9 / 10);
  EXPECT_FALSE(a.fixed_transform);
  // The coarse grid found the right neighbourhood; its curve has a minimum there.
  EXPECT_NEAR(a.coarse_offset_s, s.em_clock_offset_s, a.grid_step_s);
  EXPECT_EQ(a.grid_offset_s.size(), a.grid_rms_mm.size());
}

TEST(EmAlignment, RecoversAnOffsetFarFromTheStartDifference) {
  SyntheticRun s;
  s.image_noise_mm = 0.3;
  s.em_lead_s = 1.4;  // the EM log started 1.4 s before the volumes: the window's centre is off
  EmAlignmentOptions o;
  const EmAlignment a = AlignEmToImage(EmSeries(s), ImageTips(s), o);
  EXPECT_NEAR(a.offset_center_s, s.em_clock_offset_s + s.em_lead_s, 1e-9);
  EXPECT_NEAR(a.em_time_offset_s, s.em_clock_offset_s, kMargin * Derive(s, a).offset_s + 2e-4);
}

TEST(EmAlignment, KnownTransformEstimatesOnlyTheOffsetEvenOnALine) {
  SyntheticRun s;
  s.amplitude_mm = {8.0, 0.0, 0.0};  // along a line: the pose alone would be refused
  s.image_noise_mm = 0.1;
  EmAlignmentOptions o;
  o.em_to_image = s.em_to_image;
  const EmAlignment a = AlignEmToImage(EmSeries(s), ImageTips(s), o);
  EXPECT_TRUE(a.fixed_transform);
  EXPECT_TRUE(a.em_to_image.isApprox(s.em_to_image));
  EXPECT_NEAR(a.em_time_offset_s, s.em_clock_offset_s, kMargin * Derive(s, a).offset_s + 2e-4);
}

TEST(EmAlignment, RefusesMotionAlongALine) {
  SyntheticRun s;
  s.amplitude_mm = {8.0, 0.0, 0.0};
  const std::string msg =
      InvalidArgumentMessage([&] { AlignEmToImage(EmSeries(s), ImageTips(s)); });
  ExpectContains(msg, "moved along a line");
  ExpectContains(msg, "registration sweep");
  ExpectContains(msg, "--em-to-image");
}

TEST(EmAlignment, RefusesTooFewSamples) {
  SyntheticRun s;
  s.duration_s = 0.5;  // 10 volumes
  ExpectContains(InvalidArgumentMessage([&] { AlignEmToImage(EmSeries(s), ImageTips(s)); }),
                 "volumes with a tracked tip; at least 20 are needed");
  SyntheticRun far;
  far.em_clock_offset_s = -1000.0;
  EmAlignmentOptions o;
  o.offset_center_s = -500.0;  // a window where the logs never overlap
  ExpectContains(InvalidArgumentMessage([&] { AlignEmToImage(EmSeries(far), ImageTips(far), o); }),
                 "image tips pair with EM samples");
}

TEST(EmAlignment, NamesInchesReadAsMillimetres) {
  SyntheticRun s;
  const std::string msg =
      InvalidArgumentMessage([&] { AlignEmToImage(EmSeries(s, 1.0 / 25.4), ImageTips(s)); });
  ExpectContains(msg, "looks like inches read as mm: declare --em-units in");
  ExpectContains(InvalidArgumentMessage([&] { AlignEmToImage(EmSeries(s, 25.4), ImageTips(s)); }),
                 "looks like mm declared as inches");
}

TEST(EmAlignment, RefusesAnEmSensorThatDidNotFollowTheTip) {
  SyntheticRun s;
  PointSeries still;
  for (const formats::EmSample& e : s.EmSamples())
    still.Add(e.t_s, Eigen::Vector3d(100, -60, -158));
  ExpectContains(InvalidArgumentMessage([&] { AlignEmToImage(still, ImageTips(s)); }),
                 "the EM sensor hardly moved");
}

TEST(PointSeries, InterpolatesButNotAcrossLongGaps) {
  PointSeries p;
  p.Add(0.0, {0, 0, 0});
  p.Add(1.0, {2, 4, 6});
  p.Add(5.0, {2, 4, 6});
  EXPECT_TRUE(p.At(0.25, 1.5)->isApprox(Eigen::Vector3d(0.5, 1, 1.5)));
  EXPECT_FALSE(p.At(3.0, 1.5).has_value());
  EXPECT_FALSE(p.At(-0.1, 1.5).has_value());
  EXPECT_TRUE(p.At(5.0, 1.5).has_value());
  EXPECT_DOUBLE_EQ(p.MedianPeriodS(), 4.0);
}

}  // namespace
}  // namespace echoservo
