// End-to-end test of `echoservo calibrate temporal` and `echoservo report --tracker-lag`:
// the tracker is PLUS's own water-tank recording (data/plus); the video is written here by
// hand (a MetaImage header and raw bytes, no echoservo code) with a tank bottom whose depth
// follows that recording's real probe motion, stamped a known lag early. The lag comes back
// within 2 ms with PLUS's frame counts and a confidence, and its JSON feeds `report
// --tracker-lag`, which then uses it (not a search) and says where it came from. A video
// without pixel spacing reports its reflector in pixels only. Bad input: an unknown tool, a
// clip rectangle outside the frame, a lag file that is not one.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/plus_probe_poses.h"
#include "tests/test_util/synthetic_run.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using testing::RunCli;
using testing::RunResult;
using testing::ShellQuote;

const fs::path kTracker = fs::path(ECHOSERVO_DATA_DIR) / "plus" /
                          "WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha";

// Writes a PLUS video sequence (2D frames, 48 × 160 pixels of 0.4 mm, or ElementSpacing
// 1 1 1 without `spacing`) of a bright line at 80 px + the probe's displacement along its
// principal direction, each frame stamped `lag` before the tracker time of the motion it shows.
void WriteVideo(const fs::path& path, double lag, bool spacing = true) {
  const auto poses = testing::ScanProbePoses(kTracker);
  std::vector<double> t;
  std::vector<Eigen::Vector3d> p;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& [frame, pose] : poses) {
    t.push_back(pose.t_s);
    p.push_back(pose.p_mm);
    mean += pose.p_mm / static_cast<double>(poses.size());
  }
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& q : p) cov += (q - mean) * (q - mean).transpose();
  const Eigen::Vector3d axis =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(2);
  const int w = 48, h = 160;
  std::string header, pixels;
  std::size_t n = 0, j = 0;
  unsigned state = 1;
  for (double tau = t.front() + 0.01; tau < t.back() - 0.01; tau += 1.0 / 30.0, ++n) {
    while (t[j + 1] < tau) ++j;
    const double a = (tau - t[j]) / (t[j + 1] - t[j]);
    const double depth = 80.0 + ((1 - a) * p[j] + a * p[j + 1] - mean).dot(axis) / 0.4;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        state = state * 1103515245u + 12345u;
        const double line = std::exp(-0.5 * (y - depth) * (y - depth) / 2.0);
        pixels += static_cast<char>(static_cast<unsigned char>(180.0 * line + (state >> 27)));
      }
    char key[64];
    std::snprintf(key, sizeof key, "Seq_Frame%04zu_", n);
    char stamp[64];
    std::snprintf(stamp, sizeof stamp, "%.6f", tau - lag);
    header += std::string(key) + "Timestamp = " + stamp + "\n" + key + "ImageStatus = OK\n";
  }
  std::ofstream out(path, std::ios::binary);
  out << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
      << "CompressedData = False\nDimSize = " << w << " " << h << " " << n
      << "\nElementSpacing = " << (spacing ? "0.4 0.4 1" : "1 1 1") << "\nElementType = MET_UCHAR\n"
      << "UltrasoundImageOrientation = MF\n"
      << header << "ElementDataFile = LOCAL\n"
      << pixels;
}

TEST(CalibrateCli, TemporalLagOfRealMotionFeedsTheReport) {
  const testing::TempDir dir("calibrate_cli", true);
  const fs::path video = dir.path() / "video.igs.mha";
  const double lag = 0.0637;
  WriteVideo(video, lag);
  const std::string inputs =
      " --video " + ShellQuote(video.string()) + " --tracker " + ShellQuote(kTracker.string());
  const RunResult r = RunCli("calibrate temporal" + inputs + " --max-lag 1 --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_NEAR(j["tracker_lag_s"].get<double>(), lag, 0.002);  // issue 19's bound
  EXPECT_GT(j["correlation"].get<double>(), 0.99);
  // PLUS's stages: the video signal is every frame in the files' common range (the video's
  // first 2 frames precede the tracker's first pose: 621 − 2); the tracker is cropped by the
  // max lag, 1 s, at each end of that range: its 714 poses in 7416.680 … 7435.293 s.
  EXPECT_EQ(j["video_frames_used"].get<int>(), 619);
  EXPECT_EQ(j["tracker_frames_used"].get<int>(), 714);
  EXPECT_EQ(j["tool"], "ProbeToTracker");
  // The confidence: one motion period (1.02 s) fits in ±1 s, a second peak clearly lower.
  EXPECT_NEAR(j["confidence"]["peak_lag_s"].get<double>(), lag, 0.001);
  EXPECT_LT(j["confidence"]["lag_sd_s"].get<double>(), 0.001);
  ASSERT_TRUE(j["confidence"]["second_peak"].is_object()) << r.out;
  EXPECT_LT(j["confidence"]["second_peak"]["correlation"].get<double>(), 0.95);
  EXPECT_DOUBLE_EQ(j["video"]["pixel_spacing_mm"].get<double>(), 0.4);
  EXPECT_NEAR(j["video"]["reflector_peak_to_peak_mm"].get<double>(),
              0.4 * j["video"]["reflector_peak_to_peak_px"].get<double>(), 1e-9);
  const fs::path lag_json = dir.path() / "lag.json";
  std::ofstream(lag_json) << r.out;

  // The report of a run whose EM clock is the image clock delayed by exactly that lag.
  testing::SyntheticRun s;
  s.duration_s = 8.0;
  s.em_clock_offset_s = -j["tracker_lag_s"].get<double>();
  testing::WriteSyntheticRun(s, dir.path() / "run");
  const std::string report = "report " + ShellQuote((dir.path() / "run").string()) + " --out " +
                             ShellQuote((dir.path() / "report.html").string());
  const RunResult rep =
      RunCli(report + " --tracker-lag " + ShellQuote(lag_json.string()) + " --json");
  ASSERT_EQ(rep.rc, 0) << rep.err;
  const auto rj = nlohmann::json::parse(rep.out);
  EXPECT_DOUBLE_EQ(rj["em_time_offset_s"].get<double>(), s.em_clock_offset_s);
  EXPECT_NE(rj["em_time_offset_source"].get<std::string>().find("calibrate temporal"),
            std::string::npos);
  EXPECT_NEAR(rj["tip_to_target_rms_mm"].get<double>(), s.tip_offset_mm.norm(), 0.05);
  const std::string html = testing::ReadFile(dir.path() / "report.html");
  EXPECT_NE(html.find("lag.json"), std::string::npos);
  // A number: "given".
  const RunResult given = RunCli(report + " --tracker-lag 0.0637");
  ASSERT_EQ(given.rc, 0) << given.err;
  EXPECT_NE(given.out.find("tracker lag --tracker-lag 0.0637 s (given)"), std::string::npos)
      << given.out;

  // A video without pixel spacing (MetaIO's 1 1 1): pixels only, and says so.
  const fs::path bare = dir.path() / "bare.igs.mha";
  WriteVideo(bare, lag, false);
  const RunResult px = RunCli("calibrate temporal --video " + ShellQuote(bare.string()) +
                              " --tracker " + ShellQuote(kTracker.string()) + " --json");
  ASSERT_EQ(px.rc, 0) << px.err;
  const auto pj = nlohmann::json::parse(px.out);
  EXPECT_TRUE(pj["video"]["reflector_peak_to_peak_mm"].is_null());
  EXPECT_TRUE(pj["video"]["pixel_spacing_mm"].is_null());
  EXPECT_NE(pj["video"]["pixel_spacing"].get<std::string>().find("unknown"), std::string::npos);
  const RunResult given_spacing =
      RunCli("calibrate temporal --video " + ShellQuote(bare.string()) + " --tracker " +
             ShellQuote(kTracker.string()) + " --pixel-spacing 0.4 --json");
  ASSERT_EQ(given_spacing.rc, 0) << given_spacing.err;
  EXPECT_EQ(nlohmann::json::parse(given_spacing.out)["video"]["pixel_spacing"], "--pixel-spacing");

  // Bad input: an unknown tool (the tools listed), a clip rectangle outside the frames, a lag
  // file that is not one, both a lag and an offset centre.
  const RunResult tool = RunCli("calibrate temporal" + inputs + " --tool NeedleToTracker");
  EXPECT_NE(tool.rc, 0);
  EXPECT_NE(tool.err.find("no tool NeedleToTracker in the file, nor two tools to compose it "
                          "from (tools in the file: ProbeToTracker, ReferenceToTracker, "
                          "StylusToTracker)"),
            std::string::npos)
      << tool.err;
  const RunResult clip = RunCli("calibrate temporal" + inputs + " --clip-rect 60 0 10 10");
  EXPECT_NE(clip.rc, 0);
  EXPECT_NE(clip.err.find("clip rectangle origin (60, 0) lies outside the 48 x 160 pixel frame"),
            std::string::npos)
      << clip.err;
  const RunResult bad = RunCli(report + " --tracker-lag " + ShellQuote(video.string()));
  EXPECT_NE(bad.rc, 0);
  EXPECT_NE(bad.err.find("not the JSON of `echoservo calibrate temporal --json`"),
            std::string::npos)
      << bad.err;
  const RunResult both = RunCli(report + " --tracker-lag 0.05 --offset-center 0");
  EXPECT_NE(both.rc, 0);
  EXPECT_NE(both.err.find("--tracker-lag and --offset-center"), std::string::npos) << both.err;
  // A run on the demo's pipeline clock (s since its start): a lag alone cannot place it.
  const fs::path run_json = dir.path() / "run" / "run.json";
  nlohmann::json meta = nlohmann::json::parse(testing::ReadFile(run_json));
  meta["time_base"] = "pipeline";
  std::ofstream(run_json, std::ios::trunc) << meta.dump();
  const RunResult pipeline = RunCli(report + " --tracker-lag 0.05");
  EXPECT_NE(pipeline.rc, 0);
  EXPECT_NE(pipeline.err.find("time_base 'pipeline'"), std::string::npos) << pipeline.err;
}

}  // namespace
}  // namespace echoservo
