// The accuracy targets for the fast Radon detector, measured by the accuracy harness
// (tracking/detector_accuracy.h) on simulated volumes against the simulator's ground truth,
// in the same run as the RANSAC baseline and the exhaustive Radon reference. Small runs
// (4 volumes per class) so the suite stays fast; `echoservo bench detect` runs more.
#include "tracking/detector_accuracy.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "tests/test_util/sanitizers.h"
#include "tracking/accuracy_volumes.h"

namespace echoservo::tracking {
namespace {

const std::filesystem::path kSpine =
    std::filesystem::path(ECHOSERVO_DATA_DIR) / "plus" / "SpinePhantomFreehandReconstructed.mha";

DetectorAccuracyReport RunHarness(std::vector<std::string> classes, bool tracking, bool ransac,
                                  bool exhaustive, int volumes = 4) {
  DetectorAccuracyOptions o;
  o.volumes_per_class = volumes;
  o.classes = std::move(classes);
  o.tracking = tracking;
  o.ransac = ransac;
  o.exhaustive = exhaustive;
  o.spine_volume = kSpine;
  o.log = [](const std::string& line) { std::printf("%s\n", line.c_str()); };
  return RunDetectorAccuracy(o);
}

void Print(const MethodStats& m) {
  std::printf(
      "%-10s detected %d/%d false %d | angle %.3f/%.3f deg, offset %.3f/%.3f, tip %.3f/%.3f, "
      "target %.3f/%.3f mm"
      " (median/p95) | %.1f ms\n",
      m.method.c_str(), m.detected, m.volumes, m.false_detections, m.angle_deg.median,
      m.angle_deg.p95, m.offset_mm.median, m.offset_mm.p95, m.tip_mm.median, m.tip_mm.p95,
      m.target_mm.median, m.target_mm.p95, m.mean_detect_ms);
}

// The figures on simulated water-tank volumes: median axis error ≤ 0.5°, tip and
// target ≤ 0.5 mm; full search and tracking mode.
TEST(DetectorAccuracy, FastDetectorMeetsTheTargetsOnWaterTankVolumes) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "FastVersusRansac/water_tank runs the same harness on the same class under the sanitizers");
  const auto r = RunHarness({"water_tank"}, true, false, false);
  ASSERT_EQ(r.classes.size(), 1u);
  ASSERT_EQ(r.classes[0].volumes, 4);
  for (const char* method : {"fast", "tracking"}) {
    const MethodStats* m = r.classes[0].Method(method);
    ASSERT_NE(m, nullptr) << method;
    Print(*m);
    EXPECT_EQ(m->detection_rate, 1.0) << method;
    EXPECT_LE(m->angle_deg.median, 0.5) << method;
    EXPECT_LE(m->tip_mm.median, 0.5) << method;
    EXPECT_LE(m->target_mm.median, 0.5) << method;
  }
}

std::string ClassName(const ::testing::TestParamInfo<std::string>& info) { return info.param; }

class CatheterFree : public ::testing::TestWithParam<std::string> {};

// No false detection on catheter-free volumes, the real spine phantom included.
TEST_P(CatheterFree, FastDetectorReportsNoCatheter) {
  if (GetParam() != "spine_phantom")
    ECHOSERVO_RELEASE_SUITE_ONLY("the real spine phantom takes the same path");
  const auto r = RunHarness({GetParam()}, false, true, false);
  ASSERT_EQ(r.classes.size(), 1u);
  EXPECT_GE(r.classes[0].volumes, 1);
  for (const auto& m : r.classes[0].methods) Print(m);
  const MethodStats* fast = r.classes[0].Method("fast");
  ASSERT_NE(fast, nullptr);
  EXPECT_EQ(fast->false_detections, 0);
  EXPECT_EQ(fast->errors, 0);
}

INSTANTIATE_TEST_SUITE_P(DetectorAccuracy, CatheterFree,
                         ::testing::Values("free_annulus", "free_tank", "free_clutter",
                                           "spine_phantom"),
                         ClassName);

class FastVersusRansac : public ::testing::TestWithParam<std::string> {};

// At least as accurate as the RANSAC baseline on every catheter class, in the same run: the
// fast detector finds the catheter at least as often, and its median angle and tip errors are
// no larger. Tolerance 0.1° and 0.1 mm: with 4 volumes a median is the mean of the middle two
// draws, and below these (a quarter of the smallest voxel pitch, 0.42 mm; the angle a 0.1 mm
// shift makes over the 60 mm visible catheter) neither method resolves a difference. RANSAC's
// measured errors are 1.5–5° and 0.3–0.6 mm (docs/detector.md), the fast detector's 0.1–0.35°
// and 0.14–0.31 mm.
TEST_P(FastVersusRansac, FastIsAtLeastAsAccurate) {
  if (GetParam() != "water_tank")
    ECHOSERVO_RELEASE_SUITE_ONLY("water_tank takes the same path for both methods");
  const auto r = RunHarness({GetParam()}, false, true, false);
  ASSERT_EQ(r.classes.size(), 1u);
  const MethodStats* fast = r.classes[0].Method("fast");
  const MethodStats* ransac = r.classes[0].Method("ransac");
  ASSERT_NE(fast, nullptr);
  ASSERT_NE(ransac, nullptr);
  Print(*fast);
  Print(*ransac);
  EXPECT_GE(fast->detection_rate, ransac->detection_rate);
  if (ransac->detected == 0) return;  // nothing to compare the errors with
  ASSERT_GT(fast->detected, 0);
  EXPECT_LE(fast->angle_deg.median, ransac->angle_deg.median + 0.1);
  EXPECT_LE(fast->tip_mm.median, ransac->tip_mm.median + 0.1);
}

INSTANTIATE_TEST_SUITE_P(DetectorAccuracy, FastVersusRansac,
                         ::testing::Values("water_tank", "no_reverberation", "speckle_clutter",
                                           "shadowing", "wide_poses", "sound_speed"),
                         ClassName);

// The fast detector finds the same line as the exhaustive full-resolution search. The
// reference is the raw Radon peak line (no axis fit): on simulated catheters it is itself
// 0.7–3.6° and up to 1 mm off the true axis (the echo centroid of sheath near/far wall, wire
// and comet tail), so the agreement bound is that bias plus margin, not the 0.5° target.
TEST(DetectorAccuracy, FastAgreesWithTheExhaustiveReference) {
  ECHOSERVO_RELEASE_SUITE_ONLY("exhaustive_radon_test checks the reference search");
  const auto r = RunHarness({"water_tank"}, false, false, true, 1);
  ASSERT_EQ(r.classes.size(), 1u);
  const MethodStats* ex = r.classes[0].Method("exhaustive");
  ASSERT_NE(ex, nullptr);
  Print(*ex);
  EXPECT_EQ(ex->detected, 1);
  ASSERT_EQ(r.agreement_angle_deg.count, 1);
  std::printf("agreement: angle %.3f deg, offset %.3f mm\n", r.agreement_angle_deg.median,
              r.agreement_offset_mm.median);
  EXPECT_LT(r.agreement_angle_deg.median, 5.0);
  EXPECT_LT(r.agreement_offset_mm.median, 1.5);
  EXPECT_EQ(ex->tip_mm.count, 0);  // axis only
}

TEST(DetectorAccuracy, QuantilesAndOptions) {
  const Quantiles q = ComputeQuantiles({3.0, 1.0, 2.0, 10.0});
  EXPECT_EQ(q.count, 4);
  EXPECT_DOUBLE_EQ(q.median, 2.5);
  EXPECT_DOUBLE_EQ(q.p95, 10.0);
  EXPECT_TRUE(std::isnan(ComputeQuantiles({}).median));
  EXPECT_TRUE(std::isinf(ComputeQuantiles({1.0, INFINITY}).p95));
  DetectorAccuracyOptions o;
  o.volumes_per_class = 0;
  EXPECT_THROW(RunDetectorAccuracy(o), std::invalid_argument);
  o = {};
  o.classes = {"no_such_class"};
  EXPECT_THROW(RunDetectorAccuracy(o), std::invalid_argument);
}

// The independent generator's classes in the harness: an oblique catheter in a volume without
// beam geometry is found, the catheter-free one is not, and the per-angle volumes know their
// beams or not as their names say.
TEST(DetectorAccuracy, IndependentClassesRunInTheHarness) {
  ECHOSERVO_RELEASE_SUITE_ONLY("the detector's paths run in IndependentVolumes");
  const auto r = RunHarness({"beam_60_unknown", "indep_free"}, false, false, false, 1);
  ASSERT_EQ(r.classes.size(), 2u);
  const MethodStats* fast = r.classes[0].Method("fast");
  ASSERT_TRUE(fast);
  Print(*fast);
  EXPECT_EQ(fast->detected, 1);
  EXPECT_LT(fast->angle_deg.median, 0.5);
  EXPECT_LT(fast->tip_mm.median, 0.5);
  EXPECT_LT(std::abs(fast->tip_along_mm.median), 0.5);
  ASSERT_TRUE(r.classes[1].Method("fast"));
  EXPECT_EQ(r.classes[1].Method("fast")->false_detections, 0);
  EXPECT_TRUE(
      MakeAccuracyVolume(FindVolumeClass("beam_40"), 0, 1, false, {}).volume.has_image_to_probe());
  EXPECT_FALSE(MakeAccuracyVolume(FindVolumeClass("beam_40_unknown"), 0, 1, false, {})
                   .volume.has_image_to_probe());
}

// Issue 32's classes: a deep catheter at 56° to the beam is found, the catheter-free deep
// volumes are not.
TEST(DetectorAccuracy, DeepObliqueClassesRunInTheHarness) {
  ECHOSERVO_RELEASE_SUITE_ONLY("the detector's paths run in IndependentVolumes");
  const auto r = RunHarness({"deep_56", "deep_free"}, false, false, false, 2);
  ASSERT_EQ(r.classes.size(), 2u);
  const MethodStats* fast = r.classes[0].Method("fast");
  ASSERT_TRUE(fast);
  Print(*fast);
  EXPECT_EQ(fast->detected, 2);
  EXPECT_LT(fast->angle_deg.median, 1.0);
  EXPECT_LT(fast->tip_mm.median, 0.5);
  ASSERT_TRUE(r.classes[1].Method("fast"));
  EXPECT_EQ(r.classes[1].Method("fast")->false_detections, 0);
}

// A compact bright reflector (a tissue cube of 3–6 mm) is as bright from every side as along
// its best line: leaving its own projections out of the z-score's baseline raises its z as it
// raises a catheter's (5.6 → 9.0 on this volume, where its cross-section is dark around: tube
// 0.84), so that z counts only for a bright run of at least 12 mm (this one: 9.8 mm).
TEST(DetectorAccuracy, CompactReflectorIsNotACatheterAgainstTheRestOfTheScene) {
  const auto av = MakeAccuracyVolume(FindVolumeClass("free_clutter"), 9, 11, false, {});
  const auto det = RadonDetector().Detect(av.volume);
  std::printf("free_clutter #9 seed 11: found %d conf %.2f z %.1f tube %.2f length %.1f\n",
              det.found, det.confidence, det.peak_z, det.tubularity, det.line_length_mm);
  EXPECT_FALSE(det.found);
}

TEST(DetectorAccuracy, VolumesAreReproducibleAndSpineNeedsItsFile) {
  const auto& cls = FindVolumeClass("wide_poses");
  const auto a = MakeAccuracyVolume(cls, 1, 7, false, {});
  const auto b = MakeAccuracyVolume(cls, 1, 7, false, {});
  EXPECT_EQ(a.label, b.label);
  ASSERT_TRUE(a.truth && b.truth);
  EXPECT_EQ(a.truth->tip_mm, b.truth->tip_mm);
  EXPECT_TRUE(
      std::equal(a.volume.voxels().begin(), a.volume.voxels().end(), b.volume.voxels().begin()));
  EXPECT_NE(MakeAccuracyVolume(cls, 2, 7, false, {}).label, a.label);
  EXPECT_THROW(
      MakeAccuracyVolume(FindVolumeClass("spine_phantom"), 0, 1, false, "/no/such/file.mha"),
      std::invalid_argument);
}

}  // namespace
}  // namespace echoservo::tracking
