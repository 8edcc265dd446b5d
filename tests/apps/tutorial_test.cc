// Executes docs/lab_tutorial.md end to end: every `echoservo` command in its bash blocks,
// in order, in a scratch folder, and checks what the page says about each step.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> TutorialCommands() {
  std::ifstream doc(fs::path(ECHOSERVO_DATA_DIR) / ".." / "docs" / "lab_tutorial.md");
  std::vector<std::string> commands;
  std::string line;
  bool in_bash = false;
  while (std::getline(doc, line)) {
    if (line.rfind("```", 0) == 0) {
      in_bash = !in_bash && line == "```bash";
      continue;
    }
    if (in_bash && line.rfind("echoservo ", 0) == 0) commands.push_back(line.substr(10));
  }
  return commands;
}

TEST(Tutorial, RunsEndToEndAndTellsTheTruth) {
  ECHOSERVO_RELEASE_SUITE_ONLY("the LabCli tests run the same commands on smaller data");
  const std::vector<std::string> commands = TutorialCommands();
  ASSERT_EQ(commands.size(), 6u) << "the tutorial's steps changed: update this test";
  const fs::path dir =
      fs::temp_directory_path() / ("echoservo_tutorial_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::vector<nlohmann::json> out;
  for (const std::string& c : commands) {
    const bool measures = c.rfind("lab compare", 0) == 0 || c.rfind("lab diagnose", 0) == 0;
    const auto r = echoservo::testing::RunCli(c + (measures ? " --json" : ""), dir);
    ASSERT_EQ(r.rc, 0) << "echoservo " << c;
    out.push_back(measures ? nlohmann::json::parse(r.out) : nlohmann::json{{"text", r.out}});
  }
  // 1: 16 trials.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir / "tutorial_data"), fs::directory_iterator{}),
            32);
  // 2: tip at the noise level, force many times the force noise.
  const auto& seed = out[1];
  EXPECT_LT(seed["rms_mm"].get<double>(), 1.2 * seed["noise"]["tip_mm"].get<double>());
  EXPECT_GT(seed["force_rms_n"].get<double>(), 5.0 * seed["noise"]["force_n"].get<double>());
  // 3: capstan_friction first and significant, quoting its signature; the others not.
  const auto& diag = out[2];
  EXPECT_FALSE(diag["adequate"].get<bool>());
  EXPECT_EQ(diag["candidates"][0]["effect"], "capstan_friction");
  EXPECT_NE(diag["candidates"][0]["evidence"].get<std::string>().find("bend angle"),
            std::string::npos);
  for (std::size_t i = 1; i < diag["candidates"].size(); ++i)
    EXPECT_FALSE(diag["candidates"][i]["significant"].get<bool>());
  // 4: force error falls by more than half; mu has a standard deviation.
  const auto& fixed = out[3];
  EXPECT_LT(fixed["force_rms_n"].get<double>(), 0.5 * seed["force_rms_n"].get<double>());
  EXPECT_GT(fixed["params"]["capstan_friction.mu"]["sd"].get<double>(), 0.0);
  // 5: adequate.
  EXPECT_TRUE(out[4]["adequate"].get<bool>());
  // 6: the report exists and is one HTML page.
  std::ifstream report(dir / "tutorial_report.html");
  std::stringstream html;
  html << report.rdbuf();
  EXPECT_NE(html.str().find("<svg"), std::string::npos);
  EXPECT_NE(html.str().find("capstan_friction"), std::string::npos);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace echoservo
