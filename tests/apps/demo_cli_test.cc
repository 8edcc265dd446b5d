// `echoservo demo`: a short closed-loop run on the simulated scanner and catheter writes a
// RUN directory that `echoservo report` reads, and prints its figures as JSON. The run is
// real time on a shared machine, so only what holds under any load is asserted: the
// structure, the volume count within the scanner's schedule, and figures that are finite;
// the accuracy figures are measured by hand (docs/live.md). Bad options are clear errors.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <utility>

#include "formats/run_dir_guard.h"
#include "formats/run_record.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using testing::ReadFile;
using testing::RunCli;
using testing::ShellQuote;

// The demo's printed tip-to-target RMS and `report RUN`'s default figure are one figure: both
// score the window report/scored_window.h defines (following + two beats), print it, and agree
// within 0.02 mm (the report aligns the EM log itself: its clock offset and EM→image fit move the
// figure by a few µm). A short run at contact and a longer one at the default standoff.
TEST(DemoCli, DemoAndReportScoreTheSameWindowAndAgree) {
  ECHOSERVO_RELEASE_SUITE_ONLY("two real-time demos of 8 and 13 s");
  const testing::TempDir dir("demo_agree", true);
  for (const auto& [duration_s, standoff] : {std::pair{8, "0"}, std::pair{13, "8"}}) {
    const fs::path run = dir.path() / ("run" + std::to_string(duration_s));
    const auto r = RunCli("demo --duration " + std::to_string(duration_s) + " --standoff " +
                          standoff + " --json --out " + ShellQuote(run.string()));
    ASSERT_EQ(r.rc, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    const auto rep = RunCli("report " + ShellQuote(run.string()) + " --json --out " +
                            ShellQuote((dir.path() / "report.html").string()));
    ASSERT_EQ(rep.rc, 0) << rep.err;
    const auto rj = nlohmann::json::parse(rep.out);
    ASSERT_TRUE(j["scored_window"]["from_s"].is_number()) << r.out;
    EXPECT_DOUBLE_EQ(rj["window"]["from_s"].get<double>(),
                     j["scored_window"]["from_s"].get<double>());
    EXPECT_EQ(rj["window"]["reason"], j["scored_window"]["reason"]);
    EXPECT_EQ(j["scored_window"]["reason"].get<std::string>().rfind("servo began following at ", 0),
              0u);
    EXPECT_NEAR(rj["tip_to_target_rms_mm"].get<double>(), j["tip_to_target_rms_mm"].get<double>(),
                0.02)
        << duration_s << " s, standoff " << standoff;
  }
}

TEST(DemoCli, ShortRunWritesARunThatTheReportReads) {
  const testing::TempDir dir("demo_cli", true);
  const fs::path run = dir.path() / "run";
  // 3 harmonics: the EKF publishes after 20 volumes, not 40, so that a host that processes only
  // ~7 vol/s (an ASan build beside other tests) still follows for several seconds, and the
  // report has tip motion to align the EM log with (it refuses < 1 mm of spread). Given by
  // --set, which overrides --harmonics (live/pipeline_parameters.h).
  const auto r =
      RunCli("demo --duration 8 --harmonics 5 --set predictor.harmonics=3 --json --out " +
             ShellQuote(run.string()));
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key : {"tip_to_target_rms_mm", "true_tip_to_target_rms_mm", "latency_ms",
                          "dropped_frames", "volumes", "missed_acquisitions", "detected",
                          "em_samples", "servo_cycles", "limit_faults", "limit_violations"})
    ASSERT_TRUE(j.contains(key)) << key << " in " << r.out;
  EXPECT_EQ(j["ekf_harmonics"].get<int>(), 3);
  // 25 vol/s for 8 s: 201 slots (k/25 ≤ 8); a loaded machine may miss some, never add any.
  EXPECT_LE(j["volumes"].get<int>(), 201);
  EXPECT_GE(j["volumes"].get<int>() + j["missed_acquisitions"].get<int>(), 190);
  EXPECT_EQ(j["servo_cycles"].get<int>(), 8001);
  EXPECT_GT(j["detected"].get<int>(), 0);
  ASSERT_TRUE(j["tip_to_target_rms_mm"].is_number()) << r.out;  // NaN prints as null
  EXPECT_TRUE(std::isfinite(j["tip_to_target_rms_mm"].get<double>()));
  ASSERT_TRUE(j.contains("report_tip_to_target_rms_mm"))
      << j.value("report_error", std::string("no report_error"));
  EXPECT_TRUE(std::isfinite(j["report_tip_to_target_rms_mm"].get<double>()));
  EXPECT_EQ(j["limit_violations"].get<int>(), 0);
  // Every rejected estimate has its reason.
  int by_reason = 0;
  for (const auto& [reason, n] : j["estimates_rejected_by"].items()) by_reason += n.get<int>();
  EXPECT_EQ(by_reason, j["estimates_rejected"].get<int>()) << j["estimates_rejected_by"].dump();
  // 40 Hz EM tracker over 8 s.
  EXPECT_NEAR(j["em_samples"].get<int>(), 321, 1);
  // The servo thread's timing: every cycle timed, its overruns within the cycles; the
  // real-time settings granted or, if the system refused them, the refusal said.
  const auto& timing = j["timing"];
  EXPECT_EQ(timing["cycles"].get<int>(), 8001);
  EXPECT_LE(timing["overruns"].get<int>(), 8001);
  EXPECT_NEAR(timing["overrun_fraction"].get<double>(), timing["overruns"].get<double>() / 8001.0,
              1e-9);
  EXPECT_LE(timing["wakeup_latency_us"]["p50"].get<double>(),
            timing["wakeup_latency_us"]["p99"].get<double>());
  EXPECT_LE(timing["wakeup_latency_us"]["p99"].get<double>(),
            timing["wakeup_latency_us"]["max"].get<double>());
  const auto& rt = j["realtime"];
  EXPECT_TRUE(rt["requested"].get<bool>());
  if (!rt["fifo"].get<bool>() || !rt["memory_locked"].get<bool>()) {
    EXPECT_FALSE(rt["refusals"].empty()) << rt.dump();  // never silently ignored
  }
  EXPECT_EQ(j["deadline"]["hold_after_overruns"].get<int>(), 10);
  for (const char* f : {"run.json", "targets.csv", "servo.csv", "latency.csv", "em.csv",
                        "truth.csv", "timing.json", "tracker.json", "report.html"})
    EXPECT_TRUE(fs::exists(run / f)) << f;
  EXPECT_EQ(ReadFile(run / "em.csv").substr(0, 25), "t_s,x_mm,y_mm,z_mm,status");
  // run.json records every parameter's value, --set's included.
  const auto settings = nlohmann::json::parse(ReadFile(run / "run.json"))["settings"];
  ASSERT_TRUE(settings.is_object());
  EXPECT_EQ(settings["predictor.harmonics"].get<double>(), 3.0);
  EXPECT_EQ(settings["follower.standoff_mm"].get<double>(), 8.0);  // the demo's default
  EXPECT_GE(settings.size(), 20u);
  // The report aligns the EM log (with the run's EM calibration) and measures the run.
  const auto rep = RunCli("report " + ShellQuote(run.string()) + " --json --out " +
                          ShellQuote((dir.path() / "report.html").string()));
  ASSERT_EQ(rep.rc, 0) << rep.err;
  const auto rj = nlohmann::json::parse(rep.out);
  ASSERT_TRUE(rj["tip_to_target_rms_mm"].is_number()) << rep.out;
  EXPECT_TRUE(std::isfinite(rj["tip_to_target_rms_mm"].get<double>()));
  EXPECT_TRUE(fs::exists(dir.path() / "report.html"));
  // The report carries the run's timing.json.
  ASSERT_TRUE(rj["servo_timing"].is_object()) << rep.out;
  EXPECT_EQ(rj["servo_timing"]["cycles"], timing["cycles"]);
  EXPECT_EQ(rj["servo_timing"]["wakeup_latency_us"]["p99"], timing["wakeup_latency_us"]["p99"]);
  EXPECT_NE(ReadFile(dir.path() / "report.html").find("id=\"servo-timing\""), std::string::npos);
  // ... and its tracker.json: the demo's volume counts, shed and missed apart.
  ASSERT_TRUE(rj["tracker_volumes"].is_object()) << rep.out;
  EXPECT_EQ(rj["tracker_volumes"]["acquired"], j["volumes"]);
  EXPECT_EQ(rj["tracker_volumes"]["missed"], j["missed_acquisitions"]);
  EXPECT_EQ(rj["tracker_volumes"]["shed"], j["shed_volumes"]);
  EXPECT_EQ(rj["tracker_volumes"]["acquired"].get<std::uint64_t>(),
            rj["tracker_volumes"]["processed"].get<std::uint64_t>() +
                rj["tracker_volumes"]["shed"].get<std::uint64_t>());
}

TEST(DemoCli, BadOptionsAreClearErrors) {
  auto r = RunCli("demo --duration 0");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--duration"), std::string::npos) << r.err;
  r = RunCli("demo --standoff -1");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--standoff"), std::string::npos) << r.err;
  r = RunCli("demo --harmonics 0");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--harmonics"), std::string::npos) << r.err;
  r = RunCli("demo --duration 2 --delay-min 0.2 --delay-max 0.1");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--delay"), std::string::npos) << r.err;
}

// The RUN directory of a run that fails (demo, track --replay): formats::RunDirGuard removes
// what the process created so that the retry with the same --out works, and never what was
// there before.
void FailedRun(const fs::path& run, const char* extra_file = nullptr) {
  try {
    formats::RunDirGuard guard(run);
    formats::RunWriter writer(run, formats::RunInfo{});
    writer.AddTarget({});
    if (extra_file != nullptr) std::ofstream(run / extra_file) << "partial\n";
    throw std::runtime_error("the recording cannot be read");
  } catch (const std::exception&) {  // the failure, or RunWriter's on a RUN written before
  }
}

TEST(DemoCli, FailedRunLeavesNoHalfWrittenRunSoTheRetryWorks) {
  const testing::TempDir dir("demo_cli", true);
  const fs::path run = dir.path() / "runs" / "a" / "RUN";
  FailedRun(run, "volumes.igs.mhd");
  EXPECT_FALSE(fs::exists(dir.path() / "runs")) << "the folders the run created are removed";
  EXPECT_TRUE(fs::exists(dir.path()));
  {  // the retry writes the RUN and keeps it
    formats::RunDirGuard guard(run);
    formats::RunWriter writer(run, formats::RunInfo{});
    writer.AddTarget({});
    writer.Flush();
    guard.Keep();
  }
  EXPECT_TRUE(fs::exists(run / "run.json"));
  EXPECT_TRUE(fs::exists(run / "targets.csv"));
  // A RUN written once stays: a run that then fails on it removes nothing of it.
  FailedRun(run);
  EXPECT_TRUE(fs::exists(run / "run.json"));
  EXPECT_TRUE(fs::exists(run / "targets.csv"));
}

TEST(DemoCli, FailedRunInAUserFolderRemovesOnlyWhatItCreated) {
  const testing::TempDir dir("demo_cli", true);
  const fs::path run = dir.path() / "mine";
  fs::create_directories(run / "notes");
  std::ofstream(run / "readme.txt") << "the user's\n";
  FailedRun(run, "volumes.igs.mhd");
  EXPECT_TRUE(fs::exists(run / "readme.txt"));
  EXPECT_TRUE(fs::is_directory(run / "notes"));
  EXPECT_FALSE(fs::exists(run / "run.json"));
  EXPECT_FALSE(fs::exists(run / "targets.csv"));
  EXPECT_FALSE(fs::exists(run / "volumes.igs.mhd"));
  // A path that is a file is not the guard's: it is left alone.
  const fs::path file = dir.path() / "file";
  std::ofstream(file) << "x";
  { formats::RunDirGuard guard(file); }
  EXPECT_TRUE(fs::exists(file));
}

}  // namespace
}  // namespace echoservo
