// End-to-end tests of the echoservo command line: the binary is run as a user would
// run it, its JSON parsed, and bad input checked for a clear error and a failing exit.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "formats/trial_io.h"
#include "hw/effect_registry.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

using Result = echoservo::testing::RunResult;
using echoservo::testing::RunCli;
using echoservo::testing::TempDir;

TEST(Cli, HelpListsSubcommands) {
  const Result r = RunCli("--help");
  EXPECT_EQ(r.rc, 0);
  EXPECT_NE(r.out.find("sim"), std::string::npos);
  const Result sim = RunCli("sim --help");
  EXPECT_EQ(sim.rc, 0);
  for (const char* cmd : {"track", "friction", "backlash", "record", "effects"}) {
    EXPECT_NE(sim.out.find(cmd), std::string::npos) << cmd;
  }
}

TEST(Cli, TrackJsonReproducesTheSeedWithinTwentyPercent) {
  const Result r = RunCli("sim track --trajectory sine --compensation none --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["trajectory"], "sine");
  EXPECT_NEAR(j["mae_mm"].get<double>(), 1.28, 0.2 * 1.28);
  EXPECT_GE(j["rms_mm"].get<double>(), j["mae_mm"].get<double>());
  EXPECT_GE(j["max_mm"].get<double>(), j["rms_mm"].get<double>());
  EXPECT_NEAR(j["ratio_to_seed"].get<double>(), j["mae_mm"].get<double>() / 1.28, 1e-12);
  EXPECT_EQ(j["limit_faults"].get<int>(), 0);
}

TEST(Cli, TrackAllPrintsEveryCombination) {
  const Result r = RunCli("sim track --trajectory all --compensation all --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["results"].size(), 8u);
  for (const auto& row : j["results"]) {
    if (row["compensation"] == "adaptive") {
      EXPECT_LE(row["mae_mm"].get<double>(), 0.15) << row.dump();
    }
    if (row["compensation"] == "iterative") {
      EXPECT_EQ(row["runs"].size(), 2u);
    }
  }
}

TEST(Cli, TrackEffectsAndSetChangeThePlant) {
  // Doubling the geometric deadzone's gap is not possible from the CLI, but removing the
  // deadzone is: without backlash the uncompensated error collapses far below B/2.
  const Result r =
      RunCli("sim track --compensation none --effects coulomb_friction+viscous_friction --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_LT(nlohmann::json::parse(r.out)["mae_mm"].get<double>(), 0.3);
  const Result slow =
      RunCli("sim track --compensation none --set deadzone_traversal.tau_s=0.05 --json");
  ASSERT_EQ(slow.rc, 0) << slow.err;
  EXPECT_GT(nlohmann::json::parse(slow.out)["mae_mm"].get<double>(), 1.3);
}

TEST(Cli, BacklashSweepReproducesTheSeedModel) {
  const Result r = RunCli("sim backlash --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["configs"].size(), 24u);
  EXPECT_GE(j["model_r2"].get<double>(), 0.9);
}

TEST(Cli, FrictionSweepRecoversTheConfiguredFriction) {
  const Result r = RunCli("sim friction --effects seed --set coulomb_friction.f0_n=0.8 --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["configs"].size(), 24u);
  for (const auto& c : j["configs"]) {
    // Mean of hundreds of samples with 0.0075 N noise: a few hundredths of a newton.
    EXPECT_NEAR(c["coulomb_n"].get<double>(), 0.8, 0.03);
    EXPECT_NEAR(c["viscous_n_per_mm_s"].get<double>(), 0.006, 0.0008);
  }
}

TEST(Cli, EffectsListsTheCatalog) {
  const Result r = RunCli("sim effects --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  std::vector<std::string> names;
  for (const auto& e : j["effects"]) names.push_back(e["name"]);
  EXPECT_EQ(names, hw::EffectRegistry::WithBuiltinEffects().Names());
}

TEST(Cli, RecordWritesAReadableDataset) {
  TempDir dir("cli");
  const Result r = RunCli("sim record --out " + dir.path().string() +
                          " --configs seed --trajectories sine,mitral --tip-loads 0,1.5 "
                          "--duration 1 --effects seed+sensor_delay --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["trials"].size(), 4u);
  const std::vector<formats::Trial> trials = formats::ReadDataset(dir.path());
  ASSERT_EQ(trials.size(), 4u);
  for (const formats::Trial& t : trials) {
    EXPECT_EQ(t.size(), 1000u);
    EXPECT_NEAR(t.t_s[1] - t.t_s[0], 1e-3, 1e-12);
    EXPECT_NEAR(t.config.GapMm(), 0.8, 1e-12);
    EXPECT_TRUE(t.config.tip_load_n == 0.0 || t.config.tip_load_n == 1.5);
    EXPECT_NE(t.meta_json.find("sensor_delay"), std::string::npos);
  }
}

TEST(Cli, CatheterFileIsStrict) {
  TempDir dir("cli");
  std::filesystem::create_directories(dir.path());
  const auto good = dir.path() / "cath.json";
  std::ofstream(good) << R"({"sheath_id_mm": 2.38, "guidewire_od_mm": 1.50,
    "bends": [{"angle_deg": 180, "radius_mm": 30}], "tip_load_n": 0.5})";
  const Result ok = RunCli("sim calibrate --catheter " + good.string() + " --json");
  ASSERT_EQ(ok.rc, 0) << ok.err;
  // The loop width of this catheter is at least its deadzone π·0.88 mm.
  const auto j = nlohmann::json::parse(ok.out);
  EXPECT_NEAR(j["truth"]["deadzone_width_mm"].get<double>(), 3.141592653589793 * 0.88, 1e-9);
  EXPECT_GT(j["backlash_width_mm"].get<double>(), 0.95 * 3.141592653589793 * 0.88);

  const auto bad = dir.path() / "bad.json";
  std::ofstream(bad) << R"({"sheath_id_mm": 2.38, "guidewire_od_mm": 1.50, "bends": [],
    "tip_load_n": 0.5, "sheath_length_mm": 850})";
  const Result r = RunCli("sim track --catheter " + bad.string());
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("sheath_length_mm"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("bad.json"), std::string::npos) << r.err;

  const auto wide = dir.path() / "wide.json";
  std::ofstream(wide) << R"({"sheath_id_mm": 1.0, "guidewire_od_mm": 1.5, "bends": [],
    "tip_load_n": 0})";
  const Result w = RunCli("sim calibrate --catheter " + wide.string());
  EXPECT_NE(w.rc, 0);
  EXPECT_NE(w.err.find("guidewire_od_mm"), std::string::npos) << w.err;
  EXPECT_NE(RunCli("sim track --catheter " + (dir.path() / "missing.json").string())
                .err.find("not found"),
            std::string::npos);
}

// `tune params`: the parameter registry (live/pipeline_parameters.h) as JSON, as a table and
// by stage, and what it lists is what --set takes: every name, at its upper bound, on `track`
// (which checks its --set before it opens the recording).
TEST(Cli, TuneParamsListsEveryParameterThatSetAccepts) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "five runs of the program; the registry's own checks run in "
      "tests/live/pipeline_parameters_test.cc");
  const Result r = RunCli("tune params --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto list = nlohmann::json::parse(r.out);
  ASSERT_TRUE(list.is_array());
  ASSERT_GE(list.size(), 20u);
  std::vector<std::string> names;
  std::map<std::string, std::size_t> per_stage;
  std::string at_max;
  for (const auto& p : list) {
    const std::string name = p["name"];
    names.push_back(name);
    ++per_stage[p["stage"]];
    EXPECT_EQ(name.substr(0, name.find('.')), p["stage"].get<std::string>());
    EXPECT_LE(p["min"].get<double>(), p["default"].get<double>()) << name;
    EXPECT_LE(p["default"].get<double>(), p["max"].get<double>()) << name;
    for (const char* key : {"unit", "kind", "description"})
      EXPECT_FALSE(p[key].get<std::string>().empty()) << name << " " << key;
    at_max += " --set " + name + "=" + nlohmann::json(p["max"].get<double>()).dump();
  }
  EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));
  EXPECT_EQ(std::adjacent_find(names.begin(), names.end()), names.end());  // unique
  for (const char* name : {"detector.sheath_diameter_mm", "predictor.harmonics",
                           "predictor.init_window_s", "follower.standoff_mm", "servo.kp_n_per_mm"})
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  // The table: a header and one row per parameter, in the same order.
  const Result table = RunCli("tune params");
  ASSERT_EQ(table.rc, 0) << table.err;
  std::vector<std::string> rows;
  std::istringstream lines(table.out);
  for (std::string line; std::getline(lines, line);) rows.push_back(line.substr(0, line.find(' ')));
  ASSERT_EQ(rows.size(), names.size() + 1);
  EXPECT_EQ(rows[0], "name");
  EXPECT_TRUE(std::equal(names.begin(), names.end(), rows.begin() + 1));
  // By stage: scanner, detector, target, predictor, follower, servo.
  EXPECT_EQ(per_stage.size(), 6u);
  const Result detector = RunCli("tune params --json --stage detector");
  ASSERT_EQ(detector.rc, 0) << detector.err;
  const auto part = nlohmann::json::parse(detector.out);
  EXPECT_EQ(part.size(), per_stage["detector"]);
  for (const auto& p : part) EXPECT_EQ(p["stage"], "detector");
  EXPECT_NE(RunCli("tune params --stage tracker").err.find("unknown stage"), std::string::npos);
  // Every name at its upper bound passes `tune trial`'s --set (every stage runs there; the
  // error is then the missing recording's, not a parameter's): a 10 mm guidewire fits a 10 mm
  // sheath, contact (2 mm) is closer than a close gap of 20 mm. The lower bounds:
  // tests/live/pipeline_parameters_test.cc.
  TempDir dir("tune_params_cli", true);
  const Result t = RunCli("tune trial --recording missing.igs.mha" + at_max, dir.path());
  EXPECT_NE(t.rc, 0);
  EXPECT_NE(t.err.find("missing.igs.mha"), std::string::npos) << t.err;
  EXPECT_EQ(t.err.find("parameter"), std::string::npos) << t.err;
}

struct BadInput {
  const char* args;
  const char* expected_in_error;
};

class CliBadInput : public ::testing::TestWithParam<BadInput> {};

TEST_P(CliBadInput, FailsWithAClearMessage) {
  const Result r = RunCli(GetParam().args);
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find(GetParam().expected_in_error), std::string::npos) << r.err;
}

INSTANTIATE_TEST_SUITE_P(
    All, CliBadInput,
    ::testing::Values(BadInput{"sim track --compensation bogus", "--compensation"},
                      BadInput{"sim track --trajectory sine:5", "sine:5"},
                      BadInput{"sim track --trajectory sine:abc:1", "abc"},
                      BadInput{"sim track --duration -3", "--duration"},
                      BadInput{"sim track --duration nan", "duration"},
                      BadInput{"sim track --effects seed+warp_drive", "warp_drive"},
                      BadInput{"sim track --effects seed+seed", "named twice"},
                      BadInput{"sim track --set backlash=1", "--set"},
                      BadInput{"sim track --set deadzone_traversal.tau_s=-1",
                               "deadzone_traversal.tau_s"},
                      BadInput{"sim track --set capstan_friction.mu=1e999", "capstan_friction.mu"},
                      BadInput{"sim track --set nosuch_effect.x=1", "nosuch_effect.x"},
                      BadInput{"sim track --iterations 0", "--iterations"},
                      BadInput{"sim backlash --tip-load -1", "tip_load_n"},
                      BadInput{"sim record --out /tmp/x --tip-loads 1,,2", "--tip-loads"},
                      BadInput{"sim record --out /tmp/x --configs mars", "--configs"},
                      BadInput{"sim record", "--out"}, BadInput{"sim nosuch", "subcommand"},
                      // --set of a stage the command does not run names the ones it runs.
                      BadInput{"servo --duration 0.1 --set detector.min_confidence=0.4",
                               "does not apply to `servo` (its stage 'detector' does not run "
                               "there; it runs follower.*, servo.*)"},
                      BadInput{"servo --duration 0.1 --set follower.offset_gain=2",
                               "parameter 'follower.offset_gain' = 2: outside its bounds [0.001, "
                               "1]"},
                      BadInput{"track --sim --duration 1 --set follower.standoff_mm=3",
                               "it runs scanner.*, detector.*, target.*, predictor.*"}));

}  // namespace
}  // namespace echoservo
