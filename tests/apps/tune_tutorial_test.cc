// Executes the tutorial of docs/tuning.md end to end: every bash block, in order, in a
// scratch folder (the echoservo under test first on PATH), and checks what the page says
// about each step: the study recovers the stamp delay the recordings were made with.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using testing::ReadFile;
using testing::RunShell;
using testing::ShellQuote;

std::vector<std::string> TuneTutorialBlocks() {
  std::ifstream doc(fs::path(ECHOSERVO_DATA_DIR) / ".." / "docs" / "tuning.md");
  std::vector<std::string> blocks;
  std::string line, block;
  bool in_bash = false;
  while (std::getline(doc, line)) {
    if (line.rfind("```", 0) == 0) {
      if (in_bash) blocks.push_back(block);
      in_bash = !in_bash && line == "```bash";
      block.clear();
      continue;
    }
    if (in_bash) block += line + "\n";
  }
  return blocks;
}

// The trial of `set` with `recording`'s name in the study's report JSON.
double TuneTutorialValue(const nlohmann::json& report, const std::string& assignments,
                         std::size_t recording) {
  for (const auto& s : report["sets"])
    if (s["assignments"].get<std::string>() == assignments)
      return s["per_recording"].at(recording).get<double>();
  ADD_FAILURE() << "no set " << assignments;
  return NAN;
}

TEST(TuneTutorial, RunsEndToEndAndRecoversTheStampDelay) {
  ECHOSERVO_RELEASE_SUITE_ONLY("the TuneTrial and TuneStudy tests take the same paths");
  const std::vector<std::string> blocks = TuneTutorialBlocks();
  ASSERT_EQ(blocks.size(), 5u) << "the tutorial's steps changed: update this test";
  const fs::path dir =
      fs::temp_directory_path() / ("echoservo_tune_tutorial_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string path = fs::path(ECHOSERVO_CLI).parent_path().string();
  std::vector<testing::RunResult> out;
  for (const std::string& b : blocks) {
    out.push_back(RunShell("cd " + ShellQuote(dir.string()) + " && PATH=" + ShellQuote(path) +
                           ":$PATH bash -euo pipefail -c " + ShellQuote(b)));
    ASSERT_EQ(out.back().rc, 0) << b << "\n" << out.back().err;
  }
  // 1: six recordings.
  for (int i = 1; i <= 6; ++i)
    EXPECT_TRUE(fs::exists(dir / "rec" / ("late" + std::to_string(i) + ".igs.mha")));
  // 2: the parameter, its unit and bounds.
  EXPECT_NE(out[1].out.find("scanner.stamp_delay_s"), std::string::npos) << out[1].out;
  // 3: 30 trials, all finished; a rerun skips them all.
  const auto again = testing::RunCli("tune stamp.json --out study --jobs 2 --json", dir);
  ASSERT_EQ(again.rc, 0) << again.err;
  const auto summary = nlohmann::json::parse(again.out);
  EXPECT_EQ(summary["trials"].get<int>(), 30) << again.out;
  EXPECT_EQ(summary["skipped"].get<int>(), 30) << again.out;
  EXPECT_EQ(summary["failed"].get<int>(), 0) << again.out;
  // 4: the best set is the delay the recordings were made with, better beyond noise, with
  // no loser; the error grows with the mis-set delay on both sides.
  const auto rep = testing::RunCli("tune report study --json", dir);
  ASSERT_EQ(rep.rc, 0) << rep.err;
  const auto report = nlohmann::json::parse(rep.out);
  ASSERT_TRUE(report["best"].is_object()) << rep.out;
  const auto& best = report["best"];
  EXPECT_EQ(best["assignments"].get<std::string>(), "scanner.stamp_delay_s=0.1");
  EXPECT_TRUE(best["better_than_default"].get<bool>());
  EXPECT_LT(best["mean"].get<double>(), 0.75 * best["default_mean"].get<double>());
  const auto& vs = best["vs_default"];
  EXPECT_LT(vs["ci_high"].get<double>(), 0.0);
  EXPECT_NEAR(vs["p_value"].get<double>(), 2.0 / 64.0, 1e-9);
  for (const auto& r : report["per_recording"])
    EXPECT_FALSE(r["best_worse_than_default"].get<bool>()) << r.dump();
  for (std::size_t r = 0; r < 6; ++r) {
    const double at = TuneTutorialValue(report, "scanner.stamp_delay_s=0.1", r);
    EXPECT_LT(at, TuneTutorialValue(report, "scanner.stamp_delay_s=0.05", r)) << r;
    EXPECT_LT(at, TuneTutorialValue(report, "scanner.stamp_delay_s=0.15", r)) << r;
    EXPECT_LT(TuneTutorialValue(report, "scanner.stamp_delay_s=0.05", r),
              TuneTutorialValue(report, "", r))
        << r;
  }
  EXPECT_TRUE(fs::exists(dir / "study.html"));
  // 5: the trial by hand gives the study's figure; the replay's targets are 0.1 s earlier
  // than the stamps and its run.json records the setting.
  const auto trial = nlohmann::json::parse(out[4].out.substr(0, out[4].out.rfind('}') + 1));
  EXPECT_NEAR(trial["metrics"]["prediction.truth_rms_mm"].get<double>(),
              TuneTutorialValue(report, "scanner.stamp_delay_s=0.1", 0), 1e-9);
  const std::string run_json = ReadFile(dir / "replayed" / "run.json");
  EXPECT_NE(run_json.find("scanner.stamp_delay_s"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "replayed" / "targets.csv"));
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace echoservo
