// The detector on volumes of the independent generator (tracking/independent_volumes.h, no code
// shared with imaging/sim): catheters at 0–80° to the beam with reverberation comet tails, with
// and without known beams; deep, oblique catheters whose sheath has lost its specular echo
// (issue 32); the generator's own geometry and physics checked against its truth first.
#include "tracking/independent_volumes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <functional>
#include <initializer_list>
#include <vector>

#include "tests/test_util/constants.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/sanitizers.h"
#include "tracking/radon_detector.h"

namespace echoservo::tracking {
namespace {

using testing::kDeg;

double Median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  const std::size_t n = x.size();
  return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

TEST(IndependentVolumes, TheCatheterEchoesAtItsNearWallAndTheTruthIsConsistent) {
  IndependentVolumeOptions o;
  o.size_voxels = 64;
  o.catheter_angle_deg = 60;
  o.reverb_copies = 0;
  const IndependentVolume iv = MakeIndependentVolume(o);
  const auto& t = iv.truth;
  EXPECT_TRUE(iv.volume.has_image_to_probe());
  // The tip lies on the axis; the axis makes the asked angle with the beam at the tip.
  EXPECT_NEAR((t.tip_mm - t.axis_point_mm).normalized().dot(t.axis_direction), 1.0, 1e-9);
  EXPECT_NEAR(std::acos(std::abs(t.axis_direction.dot(iv.beam_at_tip))) / kDeg, 60.0, 1e-6);
  // 5 mm back along the shaft: the near wall (1.25 mm towards the transducer) is the catheter's
  // echo (display ≥ 240 of 255), the axis itself is dark (blood: the echo is 1.25 mm away,
  // 2 lateral σ), and the far wall is weak.
  const Eigen::Vector3d p = t.tip_mm - 12.0 * t.axis_direction;
  Eigen::Vector3d n = -(iv.beam_at_tip - iv.beam_at_tip.dot(t.axis_direction) * t.axis_direction);
  n.normalize();
  EXPECT_GT(iv.volume.Sample(p + 1.25 * n), 240.0);
  EXPECT_LT(iv.volume.Sample(p), 200.0);
  EXPECT_LT(iv.volume.Sample(p - 1.25 * n), iv.volume.Sample(p + 1.25 * n) - 30.0);
  // Without a stored pose the volume does not know its beams; parallel beams cannot be stored.
  o.store_image_to_probe = false;
  EXPECT_FALSE(MakeIndependentVolume(o).volume.has_image_to_probe());
  o.parallel_beam = true;
  o.store_image_to_probe = true;
  testing::ExpectContains(testing::InvalidArgumentMessage([&] { o.Validate(); }),
                          "store_image_to_probe");
  o = {};
  o.catheter_angle_deg = 95;
  testing::ExpectContains(testing::InvalidArgumentMessage([&] { o.Validate(); }),
                          "catheter_angle_deg");
}

// Issue 32's physics: the sheath's specular echo falls with the angle of incidence, attenuation
// and TGC scale the echoes and the noise with range, PlaceTipAtDepth puts the tip at a range.
TEST(IndependentVolumes, DepthAndObliquityPhysicsDoWhatTheySay) {
  IndependentVolumeOptions o;
  o.size_voxels = 64;
  o.catheter_angle_deg = 56;
  o.reverb_copies = 0;
  o.seed = 2;
  auto near_wall_12mm_back = [](const IndependentVolume& iv) {
    const auto& t = iv.truth;
    Eigen::Vector3d n = -(iv.beam_at_tip - iv.beam_at_tip.dot(t.axis_direction) * t.axis_direction);
    return iv.volume.Sample(t.tip_mm - 12.0 * t.axis_direction + 1.25 * n.normalized());
  };
  const double plain = near_wall_12mm_back(MakeIndependentVolume(o));
  IndependentVolumeOptions oblique = o;
  oblique.specular_width_deg = 10;
  oblique.specular_diffuse = 0.15;
  // ψ = 90° − 56° = 34°: 0.15 + 0.85·e^(−½·3.4²) = 0.153, −16.3 dB: 83 display levels of 255
  // over 50 dB.
  EXPECT_NEAR(plain - near_wall_12mm_back(MakeIndependentVolume(oblique)), 83.0, 12.0);

  // Range: speckle only (no catheter, tissue and blood alike), parallel beams; the median of
  // the top and bottom four planes, 30 mm apart along the beam.
  IndependentVolumeOptions r;
  r.size_voxels = 64;
  r.catheter = false;
  r.parallel_beam = true;
  r.store_image_to_probe = false;
  r.blood_scatter = r.tissue_scatter = 0.04;
  auto top_minus_bottom = [](const IndependentVolumeOptions& opt) {
    const imaging::Volume v = MakeIndependentVolume(opt).volume;
    const int n = opt.size_voxels;
    auto median_of_planes = [&](int k0) {
      std::vector<double> x;
      for (int k = k0; k < k0 + 4; ++k)
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i)
            x.push_back(v.voxels()[static_cast<std::size_t>(i + n * (j + n * k))]);
      return Median(x);
    };
    return median_of_planes(0) - median_of_planes(n - 4);
  };
  r.attenuation_db_per_mm = 0.3;  // 9 dB over 30 mm: 46 display levels
  EXPECT_NEAR(top_minus_bottom(r), 46.0, 6.0);
  r.tgc_db_per_mm = 0.3;  // compensated
  EXPECT_NEAR(top_minus_bottom(r), 0.0, 4.0);
  r.blood_scatter = r.tissue_scatter = 0;  // noise alone, raised by the TGC: 9 dB deeper
  r.noise_amplitude = 0.02;
  EXPECT_NEAR(top_minus_bottom(r), -46.0, 6.0);

  IndependentVolumeOptions deep;
  deep.tip_offset_mm = Eigen::Vector3d(2, -1, 3);
  PlaceTipAtDepth(deep, 87);
  const IndependentVolume dv = MakeIndependentVolume(deep);
  const Eigen::Vector3d apex = dv.volume.image_to_probe().inverse().translation();
  EXPECT_NEAR((dv.truth.tip_mm - apex).norm(), 87.0, 1e-9);
  EXPECT_THROW(PlaceTipAtDepth(deep, 10), std::invalid_argument);
  deep.attenuation_db_per_mm = 2;
  testing::ExpectContains(testing::InvalidArgumentMessage([&] { deep.Validate(); }),
                          "attenuation_db_per_mm");
  deep = {};
  deep.specular_diffuse = 1.5;
  testing::ExpectContains(testing::InvalidArgumentMessage([&] { deep.Validate(); }),
                          "specular diffuse");
}

struct Errors {
  bool found;
  double angle_deg, offset_mm, tip_mm, tip_along_mm, tubularity;
};

Errors DetectIn(const IndependentVolumeOptions& o, const RadonDetectorOptions& d = {}) {
  const IndependentVolume iv = MakeIndependentVolume(o);
  const auto det = RadonDetector(d).Detect(iv.volume);
  const auto& t = iv.truth;
  Errors e{det.found, 0, 0, 0, 0, det.tubularity};
  if (!det.found) return e;
  e.angle_deg = AngleBetweenLines(det.axis, Line3{t.axis_point_mm, t.axis_direction}) / kDeg;
  e.offset_mm = PointToLineDistance(det.axis, t.tip_mm);
  e.tip_mm = (det.tip_mm - t.tip_mm).norm();
  e.tip_along_mm = (det.tip_mm - t.tip_mm).dot(t.axis_direction);
  return e;
}

// One catheter per angle (80³ voxels, azimuth 70° × seed, seeds from `first_seed` on),
// `configure` setting the case's options; each detection is printed under `label` and must
// be found. Returns the errors of those found.
std::vector<Errors> SweepAngles(const char* label, std::initializer_list<double> angles_deg,
                                int first_seed,
                                const std::function<void(IndependentVolumeOptions&)>& configure) {
  std::vector<Errors> found;
  int seed = first_seed;
  for (double deg : angles_deg) {
    IndependentVolumeOptions o;
    o.size_voxels = 80;
    o.catheter_angle_deg = deg;
    o.catheter_azimuth_deg = 70.0 * seed;
    o.seed = static_cast<std::uint64_t>(seed++);
    configure(o);
    const Errors e = DetectIn(o);
    std::printf("%s, %2.0f deg: found %d angle %.3f offset %.3f tip %.3f (along %+.3f) tube %.2f\n",
                label, deg, e.found, e.angle_deg, e.offset_mm, e.tip_mm, e.tip_along_mm,
                e.tubularity);
    EXPECT_TRUE(e.found) << label << ", " << deg << " deg";
    if (e.found) found.push_back(e);
  }
  return found;
}

double MedianOf(const std::vector<Errors>& errors, double Errors::*field) {
  std::vector<double> v;
  for (const Errors& e : errors) v.push_back(e.*field);
  return Median(v);
}

// 0–80° to the beam, comet tails (4 copies every 2.5 mm, −6 dB each), known beams (the
// volume's image-to-probe pose): found in every volume, axis and tip within the issue's bounds.
TEST(IndependentVolumes, CatheterAtAnyAngleWithCometTailsIsFound) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "statistical sweep over angles (the detector's paths run elsewhere)");
  const std::vector<Errors> e = SweepAngles("known beams", {0.0, 20.0, 40.0, 60.0, 80.0}, 1,
                                            [](IndependentVolumeOptions&) {});
  ASSERT_FALSE(e.empty());
  EXPECT_LE(MedianOf(e, &Errors::angle_deg), 0.3);
  EXPECT_LE(MedianOf(e, &Errors::tip_mm), 0.3);
}

// The same catheters in volumes that do not know their beams: the tube check judges the comet
// tails from the cross-section (a ribbon decaying away from the catheter), so every one is
// found; where the ribbon shows the beams' projection the near-wall fit follows it, elsewhere
// (0°: the tails run along the axis; 20°: a faint ribbon) the centre-line fit stands.
TEST(IndependentVolumes, UnknownBeamsCatheterAtAnyAngleIsStillFound) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "statistical sweep over angles (the detector's paths run elsewhere)");
  const std::vector<Errors> e =
      SweepAngles("unknown beams", {0.0, 20.0, 40.0, 60.0, 80.0}, 11,
                  [](IndependentVolumeOptions& o) { o.store_image_to_probe = false; });
  ASSERT_FALSE(e.empty());
  EXPECT_LE(MedianOf(e, &Errors::angle_deg), 0.3);
  EXPECT_LE(MedianOf(e, &Errors::tip_mm), 0.3);
}

// The tip pointing away from the transducer: the wire's comet tail runs on beyond the tip along
// the axis; with known beams the tip's first-echo edge leaves it out.
TEST(IndependentVolumes, TipAwayFromTheProbeIsNotLengthenedByTheCometTail) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "statistical sweep over angles (the detector's paths run elsewhere)");
  const std::vector<Errors> e =
      SweepAngles("tip away", {20.0, 50.0, 80.0}, 21,
                  [](IndependentVolumeOptions& o) { o.tip_towards_probe = false; });
  ASSERT_FALSE(e.empty());
  EXPECT_LT(std::abs(MedianOf(e, &Errors::tip_along_mm)), 0.3);
}

// Issue 32: 50–80° to the beam, the tip 87 and 100 mm from the apex, SetDeepObliquePhysics (the
// sheath's specular echo lost to 0.15–0.4 of it, the guidewire's to 0.3–0.9, attenuation and
// TGC, noise, the lateral PSF 1.45–1.7× wider): found in every volume (the Radon z-score
// against the rest of the scene), the axis and tip fitted without the tissue ahead.
TEST(IndependentVolumes, ObliqueCatheterDeepInTheVolumeIsFound) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "statistical sweep over angles (the detector's paths run elsewhere)");
  std::vector<Errors> all;
  for (const double depth : {87.0, 100.0}) {
    const std::vector<Errors> e =
        SweepAngles(depth < 90 ? "deep 87 mm" : "deep 100 mm", {50.0, 56.0, 60.0, 70.0, 80.0},
                    depth < 90 ? 31 : 41, [depth](IndependentVolumeOptions& o) {
                      SetDeepObliquePhysics(o);
                      PlaceTipAtDepth(o, depth);
                    });
    all.insert(all.end(), e.begin(), e.end());
  }
  ASSERT_FALSE(all.empty());
  EXPECT_LE(MedianOf(all, &Errors::angle_deg), 0.6);
  EXPECT_LE(MedianOf(all, &Errors::tip_mm), 0.4);
}

// The issue's case, 56° to the beam and the tip 87 mm deep: the catheter's best lines seen from
// the side make the z-score's baseline (z ≈ 7, below the 7.8 that c_peak = 0.5 needs); against
// the rest of the scene it is clear, and tracking keeps that baseline.
TEST(IndependentVolumes, IssueCaseIsFoundAgainstTheRestOfTheScene) {
  IndependentVolumeOptions o;
  o.size_voxels = 80;
  o.catheter_angle_deg = 56;
  o.catheter_azimuth_deg = 280;
  o.tip_offset_mm = Eigen::Vector3d(-0.167, 0.941, 2.569);
  o.seed = 4;
  SetDeepObliquePhysics(o);
  PlaceTipAtDepth(o, 87);
  const IndependentVolume iv = MakeIndependentVolume(o);
  const auto det = RadonDetector().Detect(iv.volume);
  std::printf("issue case: found %d z %.1f tube %.2f length %.1f rest %d\n", det.found, det.peak_z,
              det.tubularity, det.line_length_mm, det.baseline.scores_without_line);
  ASSERT_TRUE(det.found);
  EXPECT_TRUE(det.baseline.scores_without_line);
  EXPECT_GT(det.peak_z, 10.0);
  EXPECT_LT(
      AngleBetweenLines(det.axis, Line3{iv.truth.axis_point_mm, iv.truth.axis_direction}) / kDeg,
      1.0);
  EXPECT_LT((det.tip_mm - iv.truth.tip_mm).norm(), 0.5);
}

// Parallel beams (a linear probe) given by the caller for a volume without a pose.
TEST(IndependentVolumes, ParallelBeamsGivenByTheCaller) {
  IndependentVolumeOptions o;
  o.size_voxels = 72;
  o.catheter_angle_deg = 60;
  o.parallel_beam = true;
  o.store_image_to_probe = false;
  o.beam_direction = Eigen::Vector3d(0.2, -0.1, 1.0);
  o.seed = 5;
  RadonDetectorOptions d;
  d.beams = BeamGeometry::Parallel(o.beam_direction);
  const Errors e = DetectIn(o, d);
  std::printf("parallel beams: found %d angle %.3f offset %.3f tip %.3f (along %+.3f) tube %.2f\n",
              e.found, e.angle_deg, e.offset_mm, e.tip_mm, e.tip_along_mm, e.tubularity);
  ASSERT_TRUE(e.found);
  EXPECT_LT(e.angle_deg, 0.5);
  EXPECT_LT(e.offset_mm, 0.3);
  EXPECT_LT(e.tip_mm, 0.5);
  d.beams = BeamGeometry{};
  d.beams->kind = BeamGeometry::Kind::kParallel;  // no direction
  EXPECT_THROW(RadonDetector{d}, std::invalid_argument);
}

// Speckled blood and a tissue surface, no catheter, unknown beams: nothing is reported.
TEST(IndependentVolumes, CatheterFreeVolumeIsNotFound) {
  IndependentVolumeOptions o;
  o.size_voxels = 72;
  o.catheter = false;
  o.store_image_to_probe = false;
  o.seed = 3;
  const IndependentVolume iv = MakeIndependentVolume(o);
  const auto det = RadonDetector().Detect(iv.volume);
  std::printf("catheter-free: found %d conf %.2f tube %.2f\n", det.found, det.confidence,
              det.tubularity);
  EXPECT_FALSE(det.found);
}

// Issue 32's physics without a catheter, the grid 80–95 mm deep, unknown beams: nothing.
TEST(IndependentVolumes, DeepCatheterFreeVolumesAreNotFound) {
  for (int seed = 1; seed <= 4; ++seed) {
    IndependentVolumeOptions o;
    o.size_voxels = 72;
    o.catheter = false;
    o.store_image_to_probe = false;
    o.seed = static_cast<std::uint64_t>(seed);
    SetDeepObliquePhysics(o);
    PlaceTipAtDepth(o, 75.0 + 5 * seed);
    const auto det = RadonDetector().Detect(MakeIndependentVolume(o).volume);
    std::printf("deep catheter-free %d: found %d conf %.2f z %.1f tube %.2f\n", seed, det.found,
                det.confidence, det.peak_z, det.tubularity);
    EXPECT_FALSE(det.found) << "seed " << seed;
  }
}

}  // namespace
}  // namespace echoservo::tracking
