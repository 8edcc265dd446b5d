// `echoservo demo`: a short closed-loop run on the simulated scanner and catheter writes a
// RUN directory that `echoservo report` reads, and prints its figures as JSON. The run is
// real time on a shared machine, so only what holds under any load is asserted: the
// structure, the volume count within the scanner's schedule, and figures that are finite;
// the accuracy figures are measured by hand (docs/live.md). Bad options are clear errors.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using testing::ReadFile;
using testing::RunCli;
using testing::ShellQuote;

TEST(DemoCli, ShortRunWritesARunThatTheReportReads) {
  const testing::TempDir dir("demo_cli", true);
  const fs::path run = dir.path() / "run";
  const auto r = RunCli("demo --duration 6 --json --out " + ShellQuote(run.string()));
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key : {"tip_to_target_rms_mm", "true_tip_to_target_rms_mm", "latency_ms", "dropped_frames", "volumes",
                          "detected", "em_samples", "servo_cycles", "limit_faults"})
    EXPECT_TRUE(j.contains(key)) << key;
  // 25 vol/s for 6 s: 151 slots (k/25 ≤ 6); a loaded machine may miss some, never add any.
  EXPECT_LE(j["volumes"].get<int>(), 151);
  EXPECT_GE(j["volumes"].get<int>() + j["missed_acquisitions"].get<int>(), 140);
  EXPECT_EQ(j["servo_cycles"].get<int>(), 6001);
  EXPECT_GT(j["detected"].get<int>(), 0);
  EXPECT_TRUE(std::isfinite(j["tip_to_target_rms_mm"].get<double>()));
  EXPECT_TRUE(std::isfinite(j["report_tip_to_target_rms_mm"].get<double>()));
  EXPECT_EQ(j["limit_violations"].get<int>(), 0);
  // 40 Hz EM tracker over 6 s.
  EXPECT_NEAR(j["em_samples"].get<int>(), 241, 1);
  for (const char* f : {"run.json", "targets.csv", "servo.csv", "latency.csv", "em.csv", "truth.csv", "report.html"})
    EXPECT_TRUE(fs::exists(run / f)) << f;
  EXPECT_EQ(ReadFile(run / "em.csv").substr(0, 25), "t_s,x_mm,y_mm,z_mm,status");
  // The report aligns the EM log (with the run's EM calibration) and measures the run.
  const auto rep = RunCli("report " + ShellQuote(run.string()) + " --json --out " +
                          ShellQuote((dir.path() / "report.html").string()));
  ASSERT_EQ(rep.rc, 0) << rep.err;
  const auto rj = nlohmann::json::parse(rep.out);
  EXPECT_TRUE(std::isfinite(rj["tip_to_target_rms_mm"].get<double>()));
  EXPECT_TRUE(fs::exists(dir.path() / "report.html"));
}

TEST(DemoCli, BadOptionsAreClearErrors) {
  auto r = RunCli("demo --duration 0");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--duration"), std::string::npos) << r.err;
  r = RunCli("demo --standoff -1");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--standoff"), std::string::npos) << r.err;
  r = RunCli("demo --duration 2 --delay-min 0.2 --delay-max 0.1");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--delay"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace echoservo
