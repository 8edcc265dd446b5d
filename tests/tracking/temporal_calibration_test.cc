// Temporal calibration (tracking/temporal_calibration.h, tracking/reflector_line.h): the
// reflector line's sub-pixel depth, the tracker signal of PLUS's own water-tank recording
// (data/plus, read back here by a text scan that shares no code with the sequence reader),
// the lag recovered from frames rendered here from that real probe motion and from the
// simulated scanner's sweep (imaging/sim/water_tank_sweep.h), and bad input.
#include "tracking/temporal_calibration.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "imaging/io/plus_sequence.h"
#include "imaging/sim/water_tank_sweep.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/plus_probe_poses.h"
#include "tests/test_util/sanitizers.h"
#include "tracking/reflector_line.h"

namespace echoservo::tracking {
namespace {

namespace fs = std::filesystem;
using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

const fs::path kWaterTank = fs::path(ECHOSERVO_DATA_DIR) / "plus" /
                            "WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha";

// The required accuracy of the lag (issue 19: ≤ 2 ms against the known lag).
constexpr double kLagToleranceS = 0.002;

// A frame with a bright Gaussian line (σ = 1.5 px) at depth `depth_px` in the central column,
// `slope` px per px, over uniform integer speckle in [0, 30).
std::vector<std::uint8_t> RenderLine(int width, int height, double depth_px, double slope,
                                     std::mt19937& rng) {
  std::vector<std::uint8_t> px(static_cast<std::size_t>(width * height));
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const double d = depth_px + slope * (x - 0.5 * (width - 1));
      // The Gaussian is below 1e-5 of its peak beyond 7 px (7σ/1.5): speckle only there.
      const double line =
          std::abs(y - d) < 7.0 ? std::exp(-0.5 * (y - d) * (y - d) / (1.5 * 1.5)) : 0.0;
      const double v = 200.0 * line + static_cast<double>(rng() % 30);
      px[static_cast<std::size_t>(y * width + x)] = static_cast<std::uint8_t>(std::min(255.0, v));
    }
  return px;
}

// The recording's ProbeToTracker samples, by a plain text scan of its header lines.
using testing::RawProbePose;
using testing::ScanProbePoses;

TEST(ReflectorLine, SubPixelDepthAndSlopeOfARenderedLine) {
  std::mt19937 rng(3);
  for (const double depth : {40.3, 77.75, 120.5}) {
    for (const double slope : {0.0, 0.12, -0.2}) {
      const auto px = RenderLine(80, 160, depth, slope, rng);
      const auto line = FindReflectorLine(px, 80, 160);
      ASSERT_TRUE(line.has_value()) << depth << " " << slope;
      // The centroid of a sampled Gaussian above its half level is unbiased to a few
      // hundredths of a pixel; speckle below 15 % of the peak moves it less than 0.1 px.
      EXPECT_NEAR(line->depth_px, depth, 0.1);
      EXPECT_NEAR(line->slope, slope, 0.01);
      EXPECT_EQ(line->inliers, 80);
    }
  }
  // Speckle alone is no line.
  std::vector<std::uint8_t> empty(80 * 160);
  std::uniform_int_distribution<int> speckle(0, 35);
  for (auto& v : empty) v = static_cast<std::uint8_t>(speckle(rng));
  EXPECT_FALSE(FindReflectorLine(empty, 80, 160).has_value());
  ExpectContains(InvalidArgumentMessage([&] { FindReflectorLine(empty, 81, 160); }),
                 "is not 81 x 160");
}

TEST(TemporalCalibration, TrackerSignalOfPlusWaterTankRecording) {
  const auto raw = ScanProbePoses(kWaterTank);
  ASSERT_EQ(raw.size(), 801u);
  const imaging::PlusSequence seq = imaging::ReadPlusSequence(kWaterTank);
  const TrackerSignal s = ProbeMotionSignal(seq, "", kWaterTank.string());
  EXPECT_EQ(s.tool, "ProbeToTracker");  // the default among its three tools
  EXPECT_EQ(s.frames, 801u);
  ASSERT_EQ(s.position_mm.size(), 801u);  // every status OK, times strictly increasing
  EXPECT_TRUE(s.not_ok.empty());
  // The principal direction by the test's own PCA of the scanned translations.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& [frame, pose] : raw) mean += pose.p_mm;
  mean /= static_cast<double>(raw.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& [frame, pose] : raw) cov += (pose.p_mm - mean) * (pose.p_mm - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov / static_cast<double>(raw.size()));
  const Eigen::Vector3d axis = eig.eigenvectors().col(2);
  EXPECT_GT(std::abs(axis.dot(s.axis)), 1.0 - 1e-9);
  std::size_t i = 0;
  for (const auto& [frame, pose] : raw) {
    EXPECT_DOUBLE_EQ(s.position_mm.t_s[i], pose.t_s) << frame;
    // Sign fixed by the largest axis component; values are printed with 6 digits in the file.
    EXPECT_NEAR(std::abs(s.position_mm.value[i]), std::abs((pose.p_mm - mean).dot(axis)), 1e-6);
    ++i;
  }
  // A translation sweep: the probe moves ≈ 26 mm up and down, far more than sideways.
  EXPECT_GT(s.spread_mm[0], 5.0 * s.spread_mm[1]);
  double lo = 1e9, hi = -1e9;
  for (double v : s.position_mm.value) lo = std::min(lo, v), hi = std::max(hi, v);
  EXPECT_GT(hi - lo, 20.0);
}

// Video frames of a tank bottom whose depth follows the REAL probe motion of PLUS's
// recording, stamped `lag` early (so the recording's tracker stream lags them by `lag`).
// With `ring_down`, rows 2-11 hold a static band brighter than the line (a transducer's
// ring-down), which the calibration must ignore.
imaging::PlusSequence RenderFromRealMotion(const std::map<int, RawProbePose>& raw, double lag,
                                           double rate_hz, bool inverted, bool ring_down) {
  std::vector<double> t;
  std::vector<Eigen::Vector3d> p;
  for (const auto& [frame, pose] : raw) t.push_back(pose.t_s), p.push_back(pose.p_mm);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& q : p) mean += q;
  mean /= static_cast<double>(p.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& q : p) cov += (q - mean) * (q - mean).transpose();
  const Eigen::Vector3d axis =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(2);
  imaging::PlusSequence video;
  const int width = 64, height = 200;
  video.frame_dims = {width, height, 1};
  video.spacing_mm = Eigen::Vector3d(0.4, 0.4, 1.0);
  std::mt19937 rng(11);
  std::size_t j = 0;
  for (double tau = t.front() + 0.01; tau < t.back() - 0.01; tau += 1.0 / rate_hz) {
    while (t[j + 1] < tau) ++j;
    const double w = (tau - t[j]) / (t[j + 1] - t[j]);
    const double s_mm = ((1 - w) * p[j] + w * p[j + 1] - mean).dot(axis);
    const double depth_px = 100.0 + (inverted ? -s_mm : s_mm) / 0.4;  // 0.4 mm pixels
    auto px = RenderLine(width, height, depth_px, 0.05, rng);
    if (ring_down) std::fill(px.begin() + 2 * width, px.begin() + 12 * width, std::uint8_t{250});
    video.pixels.insert(video.pixels.end(), px.begin(), px.end());
    imaging::SequenceFrame f;
    std::ostringstream stamp;
    stamp.precision(15);
    stamp << tau - lag;
    f.fields["Timestamp"] = stamp.str();
    f.fields["ImageStatus"] = "OK";
    video.frames.push_back(f);
  }
  return video;
}

TEST(TemporalCalibration, RecoversKnownLagOnRealProbeMotion) {
  const auto raw = ScanProbePoses(kWaterTank);
  const imaging::PlusSequence seq = imaging::ReadPlusSequence(kWaterTank);
  const TrackerSignal tracker = ProbeMotionSignal(seq, "ProbeToTracker", "tracker.igs.mha");
  LagOptions o;
  o.max_lag_s = 1.0;
  for (const auto& [lag, inverted, ring_down] : std::vector<std::tuple<double, bool, bool>>{
           {0.0371, true, false}, {-0.0824, false, true}, {0.1, true, false}}) {
    const imaging::PlusSequence video = RenderFromRealMotion(raw, lag, 24.0, inverted, ring_down);
    const VideoSignal v = ReflectorSignal(video, "video.igs.mha");
    EXPECT_EQ(v.no_line, 0u);
    EXPECT_TRUE(v.background_subtracted);
    if (ring_down) {  // without removing the static background the band is the "line"
      ReflectorLineOptions keep;
      keep.subtract_static_background = false;
      const VideoSignal raw_band = ReflectorSignal(video, "video.igs.mha", keep);
      ExpectContains(InvalidArgumentMessage([&] {
                       EstimateTrackerLag(raw_band.depth_px, tracker.position_mm, o,
                                          "video.igs.mha", "tracker.igs.mha");
                     }),
                     "video.igs.mha: the reflector moves 0.0 pixels");
    }
    const LagResult r =
        EstimateTrackerLag(v.depth_px, tracker.position_mm, o, "video.igs.mha", "tracker.igs.mha");
    EXPECT_NEAR(r.tracker_lag_s, lag, kLagToleranceS) << "inverted " << inverted;
    std::cout << "real motion: known lag " << 1000.0 * lag << " ms, estimated "
              << 1000.0 * r.tracker_lag_s << " ms, r " << r.correlation << "\n";
    EXPECT_GT(r.correlation, 0.99);
    // The tracker signal's sign against the depth's is not known in advance (PCA axis sign).
    EXPECT_GT(r.video_samples_used, 350u);
    EXPECT_GT(r.tracker_samples_used, 700u);
  }
}

TEST(TemporalCalibration, RecoversKnownLagOnSimulatedScannerSweep) {
  ECHOSERVO_RELEASE_SUITE_ONLY("renders 61 scanner frames per lag (~0.7 s each)");
  for (const double lag : {-0.1, 0.05}) {
    imaging::sim::WaterTankSweepOptions so;
    so.duration_s = 3.0;
    so.video_rate_hz = 20.0;
    so.tracker_lag_s = lag;
    so.seed = 7;
    const imaging::sim::WaterTankSweep sweep = imaging::sim::MakeWaterTankSweep(so);
    const VideoSignal v = ReflectorSignal(sweep.video, "sweep video");
    const TrackerSignal t = ProbeMotionSignal(sweep.tracker, "", "sweep tracker");
    EXPECT_EQ(v.no_line, 0u);
    LagOptions o;
    o.max_lag_s = 0.5;
    const LagResult r = EstimateTrackerLag(v.depth_px, t.position_mm, o, "v", "t");
    EXPECT_NEAR(r.tracker_lag_s, lag, kLagToleranceS);
    EXPECT_GT(r.correlation, 0.99);
    std::cout << "simulated scanner: known lag " << 1000.0 * lag << " ms, estimated "
              << 1000.0 * r.tracker_lag_s << " ms, r " << r.correlation << "\n";
  }
}

TEST(TemporalCalibration, BadInputNamesTheFileAndWhy) {
  imaging::PlusSequence seq = imaging::ReadPlusSequence(kWaterTank);
  // A tool that is not in the file: the tools are listed.
  const std::string absent =
      InvalidArgumentMessage([&] { ProbeMotionSignal(seq, "CatheterTipToTracker", "T.mha"); });
  ExpectContains(absent, "T.mha: no tool CatheterTipToTracker");
  ExpectContains(absent, "ProbeToTracker, ReferenceToTracker, StylusToTracker");
  // The reference never moves: not enough motion to correlate.
  const TrackerSignal still = ProbeMotionSignal(seq, "ReferenceToTracker", "T.mha");
  TimedSignal video;
  for (int i = 0; i < 400; ++i) {
    video.t_s.push_back(7416.0 + i * 0.04);
    video.value.push_back(100.0 + 40.0 * std::sin(i * 0.3));
  }
  ExpectContains(InvalidArgumentMessage(
                     [&] { EstimateTrackerLag(video, still.position_mm, {}, "V.mha", "T.mha"); }),
                 "not enough motion");
  // A video that does not move.
  const TrackerSignal probe = ProbeMotionSignal(seq, "ProbeToTracker", "T.mha");
  TimedSignal flat = video;
  for (double& v : flat.value) v = 100.0 + 0.1 * (v - 100.0);
  ExpectContains(InvalidArgumentMessage(
                     [&] { EstimateTrackerLag(flat, probe.position_mm, {}, "V.mha", "T.mha"); }),
                 "V.mha: the reflector moves");
  // Recordings that do not overlap.
  TimedSignal later = video;
  for (double& t : later.t_s) t += 1000.0;
  ExpectContains(InvalidArgumentMessage(
                     [&] { EstimateTrackerLag(later, probe.position_mm, {}, "V.mha", "T.mha"); }),
                 "record both together for longer");
  // Every transform INVALID.
  for (auto& f : seq.frames) f.fields["ProbeToTrackerTransformStatus"] = "INVALID";
  const std::string invalid =
      InvalidArgumentMessage([&] { ProbeMotionSignal(seq, "ProbeToTracker", "T.mha"); });
  ExpectContains(invalid, "T.mha: tool ProbeToTracker has 0 OK transform(s) in 801 frames");
  ExpectContains(invalid, "INVALID 801");
  // Video frames of different sizes: in a frame list, and a sequence's FrameSize field.
  std::mt19937 rng(5);
  const auto a = RenderLine(40, 80, 30.0, 0.0, rng);
  const auto b = RenderLine(40, 81, 30.0, 0.0, rng);
  const std::vector<VideoFrame> frames = {{0.0, 40, 80, a}, {0.04, 40, 81, b}};
  ExpectContains(InvalidArgumentMessage([&] { ReflectorSignal(frames, "V.mha"); }),
                 "V.mha: frame 1 is 40 x 81 pixels, frame 0 40 x 80");
  imaging::PlusSequence two;
  two.frame_dims = {40, 80, 1};
  two.pixels.insert(two.pixels.end(), a.begin(), a.end());
  two.pixels.insert(two.pixels.end(), a.begin(), a.end());
  two.frames.resize(2);
  two.frames[0].fields = {{"Timestamp", "0"}, {"FrameSize", "40 80"}};
  two.frames[1].fields = {{"Timestamp", "0.04"}, {"FrameSize", "40 81"}};
  ExpectContains(InvalidArgumentMessage([&] { ReflectorSignal(two, "V.mha"); }),
                 "V.mha: frame 1 FrameSize '40 81' differs from the sequence's DimSize 40 80");
  // The tracker file given as the video.
  ExpectContains(InvalidArgumentMessage([&] { ReflectorSignal(seq, "T.mha"); }),
                 "T.mha: no image data");
}

}  // namespace
}  // namespace echoservo::tracking
