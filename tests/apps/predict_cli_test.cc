// End-to-end tests of `echoservo predict` and of the motion lab through the CLI: the
// binary runs as a user would run it, on the real phantom trace and on traces written
// by `echoservo sim motion`; bad input fails with an error naming the file, line, column.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::RunCli;
using echoservo::testing::RunResult;
using echoservo::testing::TempDir;

const std::string kPhantom = std::string(ECHOSERVO_DATA_DIR) + "/heart_motion/phantom_20hz.csv";

TEST(PredictCli, PhantomJsonHasTheEkfAndEveryBaseline) {
  const RunResult r = RunCli("predict " + kPhantom + " --latency 0.1 --column POI_z --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const double zoh = j["baselines"]["zero_order_hold"]["rms_mm"];
  EXPECT_LE(3.0 * j["ekf_rms_mm"].get<double>(), zoh);
  for (const char* b : {"linear_extrapolation", "constant_velocity_kf"}) {
    EXPECT_GT(j["baselines"][b]["rms_mm"].get<double>(), j["ekf_rms_mm"].get<double>()) << b;
  }
  EXPECT_EQ(j["column"], "POI_z");
  EXPECT_EQ(j["measurements"], 750);
  EXPECT_GT(j["scored"].get<int>(), 600);
  // ekf_rms_mm is what ships (the competition's output); every competitor alone, and the
  // fractions of scored measurements each drove the output (they sum to 1).
  EXPECT_DOUBLE_EQ(j["ekf_rms_mm"].get<double>(), j["shipped"]["rms_mm"].get<double>());
  double chosen = 0.0;
  for (const char* c : {"heartbeat_ekf", "autoregressive", "autoregressive_ls", "ekf_ar_blend",
                        "zero_order_hold", "linear_extrapolation", "constant_velocity_kf"}) {
    EXPECT_GT(j["competitors"][c]["rms_mm"].get<double>(), 0.0) << c;
    chosen += j["chosen"][c].get<double>();
  }
  EXPECT_NEAR(chosen, 1.0, 1e-9);
  EXPECT_DOUBLE_EQ(j["chosen"]["autoregressive_ls"].get<double>(), 0.0);  // through the blend
  EXPECT_GE(j["autoregressive_ls"]["order"].get<int>(), 1);
  const double w = j["ekf_ar_blend"]["ekf_weight"].get<double>();
  EXPECT_TRUE(w >= 0.0 && w <= 1.0) << w;
  EXPECT_DOUBLE_EQ(j["competitors"]["zero_order_hold"]["rms_mm"].get<double>(), zoh);
  // The phantom beats at 71.5 bpm (assumed 20 Hz sampling): inside the band.
  EXPECT_NEAR(j["ekf"]["heart_rate_bpm"].get<double>(), 71.5, 5.0);
}

// A generated realistic trace (ectopic beats), scored against its noise-free motion: the
// shipped output beats the zero-order hold; the heart rate is null when the EKF holds none.
TEST(PredictCli, RealisticTraceShipsTheBestPredictor) {
  const RunResult r =
      RunCli("predict --realistic ectopic --seed 7 --truth truth --latency 0.1 --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_LT(j["ekf_rms_mm"].get<double>(),
            j["baselines"]["zero_order_hold"]["rms_mm"].get<double>());
  const auto& hr = j["ekf"]["heart_rate_bpm"];
  EXPECT_TRUE(hr.is_null() || (hr.get<double>() >= 30.0 && hr.get<double>() <= 220.0));
  const RunResult text = RunCli("predict --realistic fast --duration 12");
  ASSERT_EQ(text.rc, 0) << text.err;
  for (const char* part :
       {"shipped (competition)", "autoregressive", "heartbeat_ekf", "rate re-acquisition"})
    ExpectContains(text.out, part);
  const RunResult bad = RunCli("predict --realistic nope");
  EXPECT_NE(bad.rc, 0);
  ExpectContains(bad.err, "unknown class 'nope'");
  const RunResult none = RunCli("predict --json");
  EXPECT_NE(none.rc, 0);
  ExpectContains(none.err, "TRACE");
}

// The autoregressive reference (fitted on the first half, scored on the second) beside
// what ships on the same second half; the heart rate with its evidence, null on a breathing
// trace; a trace too short for the reference's split says how long it must be.
TEST(PredictCli, TheReferenceAndTheHeartRateAreReported) {
  const RunResult r = RunCli("predict " + kPhantom + " --column AP3_x --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto& ref = j["reference"];
  ASSERT_TRUE(ref.is_object()) << j.dump(2);
  EXPECT_NEAR(ref["split_s"].get<double>(), 0.5 * 749 * 0.05, 1e-6);  // 750 samples at 20 Hz
  EXPECT_GE(ref["order"].get<int>(), 16);  // about a heartbeat of lags (17 samples)
  EXPECT_GT(ref["cross_validation"].size(), 5u);
  const auto& half = j["second_half"];
  EXPECT_NEAR(half["from_s"].get<double>(), ref["split_s"].get<double>(), 1e-12);
  EXPECT_NEAR(half["shipped_over_reference"].get<double>(),
              half["shipped"]["rms_mm"].get<double>() / ref["rms_mm"].get<double>(), 1e-9);
  const auto& hr = j["ekf"]["heart_rate"];
  EXPECT_TRUE(hr["significant"].get<bool>());
  EXPECT_NEAR(j["ekf"]["heart_rate_bpm"].get<double>(), 71.5, 0.05 * 71.5);
  ExpectContains(hr["reason"].get<std::string>(), "heartbeat: 71.");
  // A breathing marker: no heart rate, and why.
  const RunResult b =
      RunCli("predict " + std::string(ECHOSERVO_DATA_DIR) + "/respiration/UAC_138.csv --json");
  ASSERT_EQ(b.rc, 0) << b.err;
  const auto jb = nlohmann::json::parse(b.out);
  EXPECT_TRUE(jb["ekf"]["heart_rate_bpm"].is_null());
  EXPECT_FALSE(jb["ekf"]["heart_rate"]["significant"].get<bool>());
  EXPECT_FALSE(jb["ekf"]["heart_rate"]["reason"].get<std::string>().empty());
  // Too short for the split: the figures still come, the reference says how long it must be.
  const RunResult s = RunCli("predict --realistic regular --duration 7 --json");
  ASSERT_EQ(s.rc, 0) << s.err;
  const auto js = nlohmann::json::parse(s.out);
  EXPECT_TRUE(js["reference"].is_null());
  EXPECT_TRUE(js["second_half"].is_null());
  ExpectContains(js["reference_note"].get<std::string>(),
                 "the trace spans 7.0 s; the autoregressive reference needs at least 8.2 s");
  const RunResult st = RunCli("predict --realistic regular --duration 7");
  ASSERT_EQ(st.rc, 0) << st.err;
  ExpectContains(st.out, "no autoregressive reference: ");
}

TEST(PredictCli, SyntheticTraceAtTheVolumeRateMeetsTheIssueFigure) {
  TempDir dir("predict_cli", true);
  const std::string trace = dir.str() + "/mitral.csv";
  ASSERT_EQ(RunCli("sim motion --out " + trace).rc, 0);
  const RunResult r = RunCli("predict " + trace + " --rate 25 --latency 0.1 --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["column"], "position");
  EXPECT_NEAR(j["measurement_rate_hz"].get<double>(), 25.0, 1e-6);
  EXPECT_LE(j["ekf_rms_mm"].get<double>(), 0.5);
  EXPECT_LE(5.0 * j["ekf_rms_mm"].get<double>(),
            j["baselines"]["zero_order_hold"]["rms_mm"].get<double>());
  // Human-readable output: the same table.
  const RunResult text = RunCli("predict " + trace + " --rate 25 --harmonics 6 --respiration");
  ASSERT_EQ(text.rc, 0) << text.err;
  for (const char* part : {"heartbeat_ekf", "zero_order_hold", "linear_extrapolation",
                           "constant_velocity_kf", "6 harmonics", "respiration term on"}) {
    ExpectContains(text.out, part);
  }
  EXPECT_FALSE(j["ekf"]["respiration"].get<bool>());  // automatic, and nothing breathes here
  EXPECT_EQ(j["ekf"]["respiration_mode"], "auto");
}

TEST(PredictCli, BreathingSwitchesTheRespirationTermOnByDefault) {
  TempDir dir("predict_cli", true);
  const std::string trace = dir.str() + "/breathing.csv";
  ASSERT_EQ(RunCli("sim motion --respiration 2.5 --duration 20 --out " + trace).rc, 0);
  const RunResult r = RunCli("predict " + trace + " --rate 25 --latency 0.1 --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["ekf"]["respiration"].get<bool>());
  EXPECT_GT(j["ekf"]["offset_rate_q_mm_s"].get<double>(), 0.0);
  const RunResult off = RunCli("predict " + trace + " --rate 25 --no-respiration --json");
  ASSERT_EQ(off.rc, 0) << off.err;
  EXPECT_FALSE(nlohmann::json::parse(off.out)["ekf"]["respiration"].get<bool>());
  const RunResult both = RunCli("predict " + trace + " --respiration --no-respiration");
  EXPECT_NE(both.rc, 0);
  ExpectContains(both.err, "excludes");
}

TEST(PredictCli, BadTracesFailWithWhereAndWhy) {
  TempDir dir("predict_cli", true);
  auto run = [&](const std::string& name, const std::string& text, const std::string& extra = "") {
    const std::string path = dir.str() + "/" + name;
    std::ofstream(path) << text;
    return RunCli("predict " + path + " " + extra);
  };
  RunResult r = run("empty.csv", "");
  EXPECT_NE(r.rc, 0);
  ExpectContains(r.err, "empty.csv: empty file");
  r = run("nan.csv", "t,x\n0,1\n0.05,nan\n");
  EXPECT_NE(r.rc, 0);
  ExpectContains(r.err, "nan.csv: line 3: column 'x': NaN");
  r = run("dup.csv", "t,x\n0,1\n0.05,2\n0.05,3\n");
  ExpectContains(r.err, "dup.csv: line 4: column 't': times must be strictly increasing");
  std::string short_trace = "t,x\n";
  for (int i = 0; i < 40; ++i)
    short_trace += std::to_string(i * 0.05) + "," + std::to_string(i % 17) + "\n";
  r = run("short.csv", short_trace);
  EXPECT_NE(r.rc, 0);
  ExpectContains(r.err, "the predictor needs more than");
  r = RunCli("predict " + kPhantom + " --column nope");
  ExpectContains(r.err, "missing required column 'nope'");
  r = RunCli("predict " + kPhantom + " --harmonics 40");
  ExpectContains(r.err, "--harmonics");
}

// A folder or a missing path is named with why and what was expected (not "read error").
TEST(PredictCli, FolderOrMissingTraceIsNamedWithWhy) {
  TempDir dir("predict_cli", true);
  RunResult r = RunCli("predict " + dir.str() + " --json");
  EXPECT_NE(r.rc, 0);
  EXPECT_TRUE(r.out.empty()) << r.out;
  ExpectContains(r.err, dir.str() + ": is a directory; expected a motion-trace CSV file");
  ExpectContains(r.err, "t,position");
  EXPECT_EQ(r.err.find("read error"), std::string::npos) << r.err;
  r = RunCli("predict " + dir.str() + "/none.csv");
  EXPECT_NE(r.rc, 0);
  ExpectContains(r.err, dir.str() + "/none.csv: no such file");
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

TEST(PredictCli, MotionLabNamesTheHiddenRespiration) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "the motion lab runs under the sanitizers in tests/lab; this case checks its statistics");
  TempDir dir("predict_cli", true);
  const std::string trace = dir.str() + "/resp.csv";
  ASSERT_EQ(
      RunCli("sim motion --out " + trace +
             " --duration 30 --sample-rate 25 --rsa 0 --wander 0 --harmonics 6 --respiration 2")
          .rc,
      0);
  const RunResult r = RunCli("lab diagnose " + trace + " --model heartbeat:6 --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_FALSE(j["adequate"].get<bool>());
  EXPECT_EQ(j["candidates"][0]["effect"], "respiration");
  const RunResult c = RunCli("lab compare " + trace + " --model heartbeat:6+respiration --json");
  ASSERT_EQ(c.rc, 0) << c.err;
  const auto cj = nlohmann::json::parse(c.out);
  EXPECT_NEAR(cj["params"]["respiration_rate"]["value"].get<double>(), 0.25, 0.01);
  const RunResult bad = RunCli("lab compare " + trace + " --model heartbeat:6+wobble");
  EXPECT_NE(bad.rc, 0);
  ExpectContains(bad.err, "unknown term 'wobble'");
}

}  // namespace
}  // namespace echoservo
