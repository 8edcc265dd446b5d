// Radon catheter-axis detector on simulated volumes (SimulatedScanner ground truth), on a
// real catheter-free volume, and on bad input.
#include "tracking/radon_detector.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "imaging/io/volume_io.h"
#include "imaging/sim/catheter_scene.h"
#include "imaging/sim/simulated_scanner.h"
#include "tests/test_util/constants.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/synthetic_volume.h"
#include "tracking/accuracy_volumes.h"

namespace echoservo::tracking {
namespace {

using imaging::sim::SimulatedScanner;
using imaging::sim::SimulatedScannerOptions;

using testing::kDeg;

struct Case {
  double yaw_deg, tilt_deg, depth_mm, lateral_mm, sound_speed, advance_mm;
};

SimulatedScannerOptions Options(const Case& c) {
  SimulatedScannerOptions o;
  imaging::sim::PlaceCatheterScene({c.yaw_deg, c.tilt_deg, c.depth_mm, c.lateral_mm, c.advance_mm},
                                   o);
  o.medium_sound_speed_m_s = c.sound_speed;
  o.reverberation = true;
  return o;
}

struct Errors {
  double angle_deg, axis_offset_mm, tip_mm, target_mm;
};

Errors Measure(const CatheterDetection& d, const imaging::FrameGroundTruth& t) {
  Errors e{};
  e.angle_deg = AngleBetweenLines(d.axis, Line3{t.axis_point_mm, t.axis_direction}) / kDeg;
  e.axis_offset_mm = PointToLineDistance(d.axis, t.tip_mm);
  e.tip_mm = (d.tip_mm - t.tip_mm).norm();
  e.target_mm = d.target_found ? (d.target_mm - t.target_mm).norm() : 1e9;
  return e;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

TEST(RadonDetector, FindsTheSimulatedCatheterAxisTipAndTarget) {
  const std::vector<Case> cases = {
      {0, 10, 60, 0, 1482, 0},   {0, 10, 60, 0, 1540, 4},   {30, 5, 55, -5, 1482, 0},
      {-20, 15, 70, 5, 1540, 2}, {180, 10, 50, 0, 1482, 0}, {15, 0, 65, 0, 1600, 0},
  };
  RadonDetector detector;
  std::vector<double> ang, off, tip, tgt;
  for (const auto& c : cases) {
    SimulatedScanner scanner(Options(c));
    const auto frame = scanner.Next();
    ASSERT_TRUE(frame && frame->truth && frame->truth->catheter_visible);
    const auto d = detector.Detect(frame->volume);
    const Errors e = Measure(d, *frame->truth);
    std::printf(
        "yaw %5.0f tilt %3.0f depth %3.0f c %4.0f: found %d conf %.2f z %.1f len %.1f tube %.2f | "
        "angle %.3f deg, "
        "offset %.3f mm, tip %.3f mm, target %.3f mm\n",
        c.yaw_deg, c.tilt_deg, c.depth_mm, c.sound_speed, d.found, d.confidence, d.peak_z,
        d.line_length_mm, d.tubularity, e.angle_deg, e.axis_offset_mm, e.tip_mm, e.target_mm);
    EXPECT_TRUE(d.found);
    ang.push_back(e.angle_deg);
    off.push_back(e.axis_offset_mm);
    tip.push_back(e.tip_mm);
    tgt.push_back(e.target_mm);
  }
  std::printf("median: angle %.3f deg, offset %.3f mm, tip %.3f mm, target %.3f mm\n", Median(ang),
              Median(off), Median(tip), Median(tgt));
  // Issue 5's figures on simulated water-tank volumes: median axis error ≤ 0.5°, tip and
  // target ≤ 0.5 mm (measured: 0.24°, 0.07 mm offset, 0.13 mm, 0.12 mm; docs/detector.md).
  EXPECT_LE(Median(ang), 0.5);
  EXPECT_LE(Median(off), 0.5);
  EXPECT_LE(Median(tip), 0.5);
  EXPECT_LE(Median(tgt), 0.5);
  // Every case within twice the median targets (worst measured: 0.43°, 0.14, 0.40, 0.24 mm).
  for (std::size_t i = 0; i < cases.size(); ++i) {
    EXPECT_LT(ang[i], 1.0) << i;
    EXPECT_LT(off[i], 1.0) << i;
    EXPECT_LT(tip[i], 1.0) << i;
    EXPECT_LT(tgt[i], 1.0) << i;
  }
}

TEST(RadonDetector, TracksAcrossFramesNearThePreviousAxis) {
  Case c{0, 10, 60, 0, 1482, 0};
  SimulatedScanner scanner(Options(c));
  RadonDetector detector;
  for (double advance : {0.0, 1.0, 2.0}) {
    scanner.SetCatheterPose({Options(c).catheter_pose.base_to_world, advance});
    const auto frame = scanner.Next();
    const auto d = detector.Track(frame->volume);
    ASSERT_TRUE(d.found) << advance;
    const Errors e = Measure(d, *frame->truth);
    std::printf("track advance %.0f: tracked %d conf %.2f angle %.3f tip %.3f\n", advance,
                d.tracked, d.confidence, e.angle_deg, e.tip_mm);
    EXPECT_EQ(d.tracked, advance > 0.0);
    EXPECT_LE(e.angle_deg, 0.5);                                         // measured 0.04–0.29°
    EXPECT_LE(e.tip_mm, 0.5);                                            // measured 0.05–0.13 mm
    EXPECT_GT(d.axis.direction.dot(frame->truth->axis_direction), 0.0);  // points to the tip
  }
}

// A volume that does not know its beams: the full search infers them from the catheter's
// reverberation ribbon and keeps them in its baseline; tracking fits with them at once (the
// probe does not turn between volumes) and stays as accurate as the full search on the next
// frame (independent generator, catheter at 40° to the beam, 2 volumes: measured 0.04–0.08°
// and 0.08–0.10 mm tracked, 0.08° and 0.08–0.12 mm by a full search).
TEST(RadonDetector, TrackingReusesTheBeamsTheFullSearchInferred) {
  const VolumeClass& cls = FindVolumeClass("beam_40_unknown");
  RadonDetector detector;
  for (int i = 0; i < 2; ++i) {
    const AccuracyVolume av = MakeAccuracyVolume(cls, i, 1, true, {});
    ASSERT_TRUE(av.next_volume && av.next_truth);
    const CatheterDetection full = detector.Detect(av.volume);
    ASSERT_TRUE(full.found) << i;
    ASSERT_TRUE(full.baseline.inferred_beams.has_value()) << i;
    const CatheterDetection tracked = detector.Detect(*av.next_volume, full);
    ASSERT_TRUE(tracked.found && tracked.tracked) << i;
    ASSERT_TRUE(tracked.baseline.inferred_beams.has_value()) << i;
    EXPECT_EQ(tracked.baseline.inferred_beams->axis, full.baseline.inferred_beams->axis);
    const CatheterDetection fresh = detector.Detect(*av.next_volume);
    const Errors e = Measure(tracked, *av.next_truth), f = Measure(fresh, *av.next_truth);
    std::printf("volume %d: tracked angle %.3f tip %.3f, full search angle %.3f tip %.3f\n", i,
                e.angle_deg, e.tip_mm, f.angle_deg, f.tip_mm);
    EXPECT_LE(e.angle_deg, 0.5);  // the catheter classes' bound (detector_accuracy_test.cc)
    EXPECT_LE(e.tip_mm, 0.5);
    EXPECT_LE(e.tip_mm, f.tip_mm + 0.2);  // within the tip's per-volume spread of the full search
  }
}

// The guidewire rings: each echo's comet tail runs deeper along its beam, from the wire's last
// echoes too, and with the axis tilted 10° towards depth the beam has a component along it, so
// a tip edge of all echoes lies beyond the true tip (measured +0.29–0.33 mm mean over the
// demo's volumes; +0.06 mm with the simulator's reverberation off). On first echoes only
// (EdgeOptions::tip_first_echo_mm) the edge is the wire's own echo blurred by the symmetric
// point-spread function: unbiased. Signed along the axis, over 12 volumes (advances 0–5.5 mm,
// speckle seeds 1–12): the per-volume spread is ~0.2 mm, so the mean's standard error is
// ~0.06 mm and 0.12 mm is two of them.
TEST(RadonDetector, TipEdgeOnFirstEchoesIsUnbiasedUnderReverberation) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "a mean over 24 detections; FindsTheSimulatedCatheterAxisTipAndTarget takes that path");
  Case c{0, 10, 60, 0, 1482, 0};
  RadonDetectorOptions all_echoes;
  all_echoes.edge.tip_first_echo_mm = 0.0;
  const RadonDetector first(RadonDetectorOptions{}), plain(all_echoes);
  double sum_first = 0.0, sum_plain = 0.0;
  int n = 0;
  for (int i = 0; i < 12; ++i) {
    SimulatedScannerOptions o = Options(c);
    o.seed = static_cast<std::uint64_t>(i + 1);
    SimulatedScanner scanner(o);
    scanner.SetCatheterPose({o.catheter_pose.base_to_world, 0.5 * i});
    const auto frame = scanner.Next();
    ASSERT_TRUE(frame && frame->truth);
    const auto a = first.Detect(frame->volume), b = plain.Detect(frame->volume);
    ASSERT_TRUE(a.found && b.found) << i;
    const Eigen::Vector3d axis = frame->truth->axis_direction;
    sum_first += (a.tip_mm - frame->truth->tip_mm).dot(axis);
    sum_plain += (b.tip_mm - frame->truth->tip_mm).dot(axis);
    ++n;
  }
  const double mean_first = sum_first / n, mean_plain = sum_plain / n;
  std::printf(
      "signed tip error along the axis, mean of %d: first echoes %+.3f mm, all echoes %+.3f mm\n",
      n, mean_first, mean_plain);
  EXPECT_LE(std::abs(mean_first), 0.12);
  EXPECT_GE(mean_plain - mean_first, 0.15);  // the comet tails' share
}

TEST(RadonDetector, RejectsABadTipFirstEchoLookBack) {
  RadonDetectorOptions o;
  o.edge.tip_first_echo_mm = -1.0;
  EXPECT_THROW(RadonDetector{o}, std::invalid_argument);
}

using testing::Synthetic;

TEST(RadonDetector, BadInputIsNeverAFabricatedAxis) {
  const RadonDetector detector;
  auto not_found_or_error = [&](const imaging::Volume& v, const char* what) {
    try {
      const auto d = detector.Detect(v);
      EXPECT_FALSE(d.found) << what;
    } catch (const std::invalid_argument&) {
    }
  };
  not_found_or_error(Synthetic(64, 0.5, 0), "all zero");
  not_found_or_error(Synthetic(64, 0.5, 128), "constant");
  not_found_or_error(Synthetic(64, 0.5, 255), "saturated");
  not_found_or_error(Synthetic(7, 0.5, 200), "tiny");
  {
    auto v = Synthetic(64, 0.5, 20);
    for (int i = 0; i < 64; ++i) v.at(i, 32, 32) = 250;  // a line, but in a 1:8 anisotropic grid
    imaging::VolumeGeometry g = v.geometry();
    g.spacing_mm = Eigen::Vector3d(0.25, 0.25, 2.0);
    auto a = imaging::Volume::Create(g, 20);
    std::copy(v.voxels().begin(), v.voxels().end(), a.voxels().begin());
    EXPECT_THROW(detector.Detect(a), std::invalid_argument);
  }
  {
    // Speckle-like noise without a line.
    auto v = Synthetic(80, 0.5, 0);
    std::uint32_t state = 12345;
    for (auto& x : v.voxels()) {
      state = state * 1664525u + 1013904223u;
      x = static_cast<std::uint8_t>(60 + (state >> 24) % 60);
    }
    not_found_or_error(v, "noise");
  }
}

TEST(RadonDetector, SyntheticBrightLineIsFoundWithSubVoxelAccuracy) {
  auto v = Synthetic(96, 0.5, 0);
  std::uint32_t state = 7;
  for (auto& x : v.voxels()) {
    state = state * 1664525u + 1013904223u;
    x = static_cast<std::uint8_t>(40 + (state >> 24) % 40);
  }
  const Eigen::Vector3d p0(10.0, 24.3, 20.7), dir = Eigen::Vector3d(1.0, 0.15, 0.25).normalized();
  const double tip_s = 30.0;  // mm along dir from p0; the line enters at the volume's x = 0 face
  for (int k = 0; k < 96; ++k)
    for (int j = 0; j < 96; ++j)
      for (int i = 0; i < 96; ++i) {
        const Eigen::Vector3d p = v.IndexToPhysical(Eigen::Vector3d(i, j, k));
        const double s = (p - p0).dot(dir);
        const double r = (p - p0 - s * dir).norm();
        if (s <= tip_s && r < 1.5) {
          const double val = 250.0 * std::exp(-r * r / (2 * 0.4 * 0.4));
          v.at(i, j, k) = static_cast<std::uint8_t>(std::max<double>(v.at(i, j, k), val));
        }
      }
  RadonDetectorOptions o;  // a bright line, not a tube: no near-wall offset
  o.fit.sheath_diameter_mm = 0;
  o.fit.wire_diameter_mm = 0;
  const auto d = RadonDetector(o).Detect(v);
  ASSERT_TRUE(d.found);
  const double angle = AngleBetweenLines(d.axis, Line3{p0, dir}) / kDeg;
  const double tip = (d.tip_mm - (p0 + tip_s * dir)).norm();
  std::printf("synthetic: angle %.3f deg, offset %.3f mm, tip %.3f mm, conf %.2f\n", angle,
              PointToLineDistance(d.axis, p0), tip, d.confidence);
  EXPECT_LT(angle, 0.5);
  EXPECT_LT(PointToLineDistance(d.axis, p0), 0.25);
  EXPECT_LT(tip, 1.0);
  EXPECT_GT(d.axis.direction.dot(dir), 0.0);
}

TEST(RadonDetector, CatheterFreeVolumesAreNotFound) {
  for (bool annulus : {true, false}) {
    SimulatedScannerOptions o;
    o.catheter = false;
    o.annulus = annulus;
    SimulatedScanner scanner(o);
    const auto frame = scanner.Next();
    const auto d = RadonDetector().Detect(frame->volume);
    std::printf("catheter-free (annulus %d): found %d conf %.2f z %.1f len %.1f tube %.2f\n",
                annulus, d.found, d.confidence, d.peak_z, d.line_length_mm, d.tubularity);
    EXPECT_FALSE(d.found);
    // The tank floor is a bright plane: its best Radon line lies within it, which only the
    // tube test rejects (tubularity measured 0.00; a catheter measures ≥ 0.99).
    EXPECT_LT(d.tubularity, 0.3);
  }
}

TEST(RadonDetector, RealSpinePhantomVolumeIsNotFound) {
  const auto path =
      std::filesystem::path(ECHOSERVO_DATA_DIR) / "plus" / "SpinePhantomFreehandReconstructed.mha";
  const auto v = imaging::ReadVolume(path);
  CatheterDetection d;
  try {
    d = RadonDetector().Detect(v);
  } catch (const std::invalid_argument&) {
    return;
  }
  std::printf("spine: found %d conf %.2f z %.1f len %.1f tube %.2f\n", d.found, d.confidence,
              d.peak_z, d.line_length_mm, d.tubularity);
  EXPECT_FALSE(d.found);
}

}  // namespace
}  // namespace echoservo::tracking
