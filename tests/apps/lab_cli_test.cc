// End-to-end tests of `echoservo lab compare|diagnose`: the binary is run as a user
// would run it on a dataset recorded with `echoservo sim record`, its JSON parsed, and
// bad input checked for a failing exit and an error that names the file, the line where
// there is one, and the problem; with --skip-bad the bad trial is skipped and listed.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/temp_dir.h"
#include "tests/test_util/trial_files.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using Result = echoservo::testing::RunResult;
using echoservo::testing::BadCell;
using echoservo::testing::BadTrial;
using echoservo::testing::MalformedJsonSidecar;
using echoservo::testing::MissingJsonSidecar;
using echoservo::testing::MissingLastColumn;
using echoservo::testing::RunCli;
using echoservo::testing::TempDir;

constexpr const char* kTag = "lab_cli";

void Record(const TempDir& dir, const std::string& args) {
  const Result r = RunCli("sim record --out " + dir.str() + " " + args);
  ASSERT_EQ(r.rc, 0) << r.err;
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// ---------------------------------------------------------------------- JSON output

// 8 catheters × the 0.8 Hz sine, 2 s, with a hidden sensor delay.
void RecordDelayed(const TempDir& dir) {
  Record(dir, "--configs lab --trajectories sine:4:0.8 --duration 2 --effects seed+sensor_delay");
}

void ExpectGroups(const nlohmann::json& groups, const std::string& what,
                  std::size_t total_samples) {
  ASSERT_TRUE(groups.is_array()) << what;
  ASSERT_FALSE(groups.empty()) << what;
  std::size_t samples = 0;
  double sample_share = 0.0, tip_share = 0.0;
  for (const auto& g : groups) {
    for (const char* key : {"group", "samples", "tip_rms_mm", "force_rms_n", "sample_share",
                            "tip_share", "force_share"}) {
      EXPECT_TRUE(g.contains(key)) << what << " lacks " << key << ": " << g.dump();
    }
    EXPECT_GE(g["tip_rms_mm"].get<double>(), 0.0);
    samples += g["samples"].get<std::size_t>();
    sample_share += g["sample_share"].get<double>();
    tip_share += g["tip_share"].get<double>();
  }
  EXPECT_EQ(samples, total_samples) << what;  // every sample in exactly one group
  EXPECT_NEAR(sample_share, 1.0, 1e-9) << what;
  EXPECT_NEAR(tip_share, 1.0, 1e-9) << what;
}

TEST(LabCli, CompareJsonHasErrorsParametersAndBreakdown) {
  TempDir dir(kTag);
  RecordDelayed(dir);
  const Result r = RunCli("lab compare " + dir.str() + " --model seed --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["model"], "seed");
  // The seed model misses the delay: the tip error is well above the 0.03 mm noise.
  EXPECT_GT(j["rms_mm"].get<double>(), 2.0 * j["noise"]["tip_mm"].get<double>());
  EXPECT_GT(j["force_rms_n"].get<double>(), 0.0);
  for (const char* p :
       {"coulomb_friction.f0_n", "coulomb_friction.mu_tip", "viscous_friction.b_n_per_mm_s"}) {
    ASSERT_TRUE(j["params"].contains(p)) << j["params"].dump();
    EXPECT_TRUE(j["params"][p]["value"].is_number()) << p;
    EXPECT_TRUE(j["params"][p]["sd"].is_number()) << p;  // identifiable: a number, not null
    EXPECT_GT(j["params"][p]["sd"].get<double>(), 0.0) << p;
    EXPECT_TRUE(j["params"][p]["unit"].is_string()) << p;
  }
  EXPECT_NEAR(j["params"]["coulomb_friction.f0_n"]["value"].get<double>(), 0.55, 0.05);
  const std::size_t total = 8 * 2000;
  for (const char* axis : {"phase", "speed", "gap", "bend", "tip_load", "trial"}) {
    ASSERT_TRUE(j["breakdown"].contains(axis)) << axis;
    ExpectGroups(j["breakdown"][axis], axis, total);
  }
  EXPECT_EQ(j["breakdown"]["trial"].size(), 8u);
  EXPECT_EQ(j["breakdown"]["gap"].size(), 4u);  // the lab catheters' four gaps
  EXPECT_EQ(j["trials"].size(), 8u);
  EXPECT_TRUE(j["skipped"].empty());

  // With the delay in the model the tip error drops to the noise.
  const Result fixed = RunCli("lab compare " + dir.str() + " --model seed+sensor_delay --json");
  ASSERT_EQ(fixed.rc, 0) << fixed.err;
  const auto f = nlohmann::json::parse(fixed.out);
  EXPECT_NEAR(f["rms_mm"].get<double>(), f["noise"]["tip_mm"].get<double>(),
              0.1 * f["noise"]["tip_mm"].get<double>());
  EXPECT_NEAR(f["params"]["sensor_delay.delay_s"]["value"].get<double>(), 0.005, 0.0005);
}

TEST(LabCli, DiagnoseJsonRanksTheMissingEffectFirst) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "the diagnosis runs under the sanitizers in Diagnose.SeedDataIsAdequateForTheSeedModel; "
      "this case checks its ranking statistics");
  TempDir dir(kTag);
  RecordDelayed(dir);
  const Result r = RunCli("lab diagnose " + dir.str() + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["model"], "seed");
  EXPECT_TRUE(j["rms_mm"].is_number());
  EXPECT_TRUE(j["force_rms_n"].is_number());
  ASSERT_TRUE(j["adequate"].is_boolean());
  EXPECT_FALSE(j["adequate"].get<bool>());
  const auto& c = j["candidates"];
  ASSERT_EQ(c.size(), 7u);
  EXPECT_EQ(c[0]["effect"], "sensor_delay");
  EXPECT_TRUE(c[0]["significant"].get<bool>());
  EXPECT_LT(c[0]["rms_mm"].get<double>(), 0.5 * j["rms_mm"].get<double>());
  for (std::size_t i = 0; i < c.size(); ++i) {
    for (const char* key :
         {"effect", "rms_mm", "force_rms_n", "evidence", "significant", "score"}) {
      EXPECT_TRUE(c[i].contains(key)) << key << " in " << c[i].dump();
    }
    EXPECT_FALSE(c[i]["evidence"].get<std::string>().empty());
    // Best first: significant candidates before the others, each group by falling score.
    if (i > 0) {
      const bool sig_prev = c[i - 1]["significant"].get<bool>();
      const bool sig = c[i]["significant"].get<bool>();
      EXPECT_TRUE(sig_prev || !sig) << i;
      if (sig_prev == sig) {
        EXPECT_GE(c[i - 1]["score"].get<double>(), c[i]["score"].get<double>()) << i;
      }
    }
  }
  EXPECT_TRUE(Contains(c[0]["evidence"].get<std::string>(), "tip RMS")) << c[0]["evidence"];
  EXPECT_EQ(j["verdict"].get<std::string>(), "missing_effect");
  EXPECT_FALSE(j["adequate"].get<bool>());
  EXPECT_TRUE(Contains(j["summary"].get<std::string>(), "sensor_delay")) << j["summary"];
  EXPECT_TRUE(j["proposal"].is_null());  // a catalog effect explains it: nothing to discover

  // The text form names the missing effect and the next command.
  const Result text = RunCli("lab diagnose " + dir.str());
  ASSERT_EQ(text.rc, 0) << text.err;
  EXPECT_TRUE(Contains(text.out, "MISSING")) << text.out;
  EXPECT_TRUE(Contains(text.out, "--model seed+sensor_delay")) << text.out;

  // With the delay in the model nothing is missing.
  const Result adequate = RunCli("lab diagnose " + dir.str() + " --model seed+sensor_delay --json");
  ASSERT_EQ(adequate.rc, 0) << adequate.err;
  EXPECT_TRUE(nlohmann::json::parse(adequate.out)["adequate"].get<bool>()) << adequate.out;
}

// ---------------------------------------------------------------------- bad input

class LabCliBadInput : public ::testing::TestWithParam<BadTrial> {
 protected:
  // Two good trials (the seed catheter, sine and mitral, 1 s) and a copy of the first,
  // "zz_bad", corrupted.
  void SetUp() override {
    Record(dir_, "--configs seed --trajectories sine,mitral --duration 1");
    const fs::path first = echoservo::testing::FirstTrialCsv(dir_.path());
    ASSERT_FALSE(first.empty());
    GetParam().corrupt(echoservo::testing::CopyTrial(first, dir_.path(), "zz_bad"));
  }
  TempDir dir_{kTag};
};

TEST_P(LabCliBadInput, FailsNamingTheFileAndTheProblem) {
  for (const char* cmd : {"compare", "diagnose"}) {
    const Result r = RunCli(std::string("lab ") + cmd + " " + dir_.str() + " --json");
    EXPECT_NE(r.rc, 0) << cmd;
    EXPECT_TRUE(r.out.empty()) << cmd << ": " << r.out;
    EXPECT_TRUE(Contains(r.err, "zz_bad")) << cmd << ": " << r.err;
    for (const std::string& part : GetParam().expected)
      EXPECT_TRUE(Contains(r.err, part)) << part << " in " << r.err;
  }
}

TEST_P(LabCliBadInput, SkipBadListsTheFileAndGoesOn) {
  for (const char* cmd : {"compare", "diagnose"}) {
    const Result r = RunCli(std::string("lab ") + cmd + " " + dir_.str() + " --json --skip-bad");
    ASSERT_EQ(r.rc, 0) << cmd << ": " << r.err;
    EXPECT_TRUE(Contains(r.err, "skipped")) << r.err;
    EXPECT_TRUE(Contains(r.err, "zz_bad")) << r.err;
    for (const std::string& part : GetParam().expected)
      EXPECT_TRUE(Contains(r.err, part)) << part << " in " << r.err;
    const auto j = nlohmann::json::parse(r.out);
    ASSERT_EQ(j["skipped"].size(), 1u);
    EXPECT_TRUE(Contains(j["skipped"][0].get<std::string>(), "zz_bad")) << j["skipped"].dump();
    if (std::string(cmd) == "compare") {
      EXPECT_EQ(j["trials"].size(), 2u);
    } else {
      EXPECT_EQ(j["candidates"].size(), 7u);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Kinds, LabCliBadInput,
    ::testing::Values(
        BadTrial{"MissingColumn",
                 MissingLastColumn(),  // drops `force`
                 {"zz_bad.csv", "line 1", "missing required column 'force'"}},
        BadTrial{"NonNumericCell",
                 BadCell(5, 3, "1.2.3"),
                 {"zz_bad.csv", "line 5", "column 'tip'", "not a number"}},
        BadTrial{"NaN", BadCell(9, 2, "NaN"), {"zz_bad.csv", "line 9", "column 'base'", "NaN"}},
        BadTrial{"NonMonotonicTime",
                 BadCell(30, 0, "0.01"),
                 {"zz_bad.csv", "line 30", "strictly increasing"}},
        BadTrial{"MissingJsonSidecar", MissingJsonSidecar(), {"zz_bad.json", "JSON"}},
        BadTrial{"MalformedJson",
                 MalformedJsonSidecar("{\"bends\": ["),
                 {"zz_bad.json", "JSON parse error"}}),
    echoservo::testing::BadTrialName);

TEST(LabCli, SkipBadListsEveryBadFile) {
  // Every kind of bad trial at once, next to two good ones: each is listed on stderr
  // and in the JSON, and the good trials are fitted.
  TempDir dir(kTag);
  Record(dir, "--configs seed --trajectories sine,mitral --duration 1");
  const fs::path first = echoservo::testing::FirstTrialCsv(dir.path());
  ASSERT_FALSE(first.empty());
  const std::vector<BadTrial> kinds = {{"bad_cell", BadCell(5, 3, "x"), {}},
                                       {"bad_nan", BadCell(5, 4, "nan"), {}},
                                       {"bad_time", BadCell(6, 0, "0"), {}},
                                       {"bad_nojson", MissingJsonSidecar(), {}},
                                       {"bad_json", MalformedJsonSidecar("[1,"), {}}};
  for (const BadTrial& k : kinds)
    k.corrupt(echoservo::testing::CopyTrial(first, dir.path(), k.name));
  const Result r = RunCli("lab compare " + dir.str() + " --json --skip-bad");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["trials"].size(), 2u);
  ASSERT_EQ(j["skipped"].size(), kinds.size()) << j["skipped"].dump();
  for (const BadTrial& k : kinds) {
    EXPECT_TRUE(Contains(r.err, "skipped")) << r.err;
    EXPECT_TRUE(Contains(r.err, k.name)) << k.name << " in " << r.err;
    EXPECT_TRUE(Contains(j["skipped"].dump(), k.name)) << k.name;
  }
  // Without --skip-bad the first bad file (in name order) stops the command.
  const Result strict = RunCli("lab compare " + dir.str() + " --json");
  EXPECT_NE(strict.rc, 0);
  EXPECT_TRUE(Contains(strict.err, "bad_")) << strict.err;
}

TEST(LabCli, UnknownEffectInTheModelIsNamed) {
  TempDir dir(kTag);
  Record(dir, "--configs seed --trajectories sine --duration 1");
  for (const char* cmd : {"compare", "diagnose"}) {
    const Result r =
        RunCli(std::string("lab ") + cmd + " " + dir.str() + " --model seed+warp_drive --json");
    EXPECT_NE(r.rc, 0) << cmd;
    EXPECT_TRUE(Contains(r.err, "warp_drive")) << r.err;
    EXPECT_TRUE(Contains(r.err, "unknown effect")) << r.err;
  }
}

TEST(LabCli, MissingOrEmptyDatasetFolderIsNamed) {
  TempDir dir(kTag);
  const Result missing = RunCli("lab compare " + dir.str() + " --json");
  EXPECT_NE(missing.rc, 0);
  EXPECT_TRUE(Contains(missing.err, dir.str())) << missing.err;
  EXPECT_TRUE(Contains(missing.err, "not found")) << missing.err;
  fs::create_directories(dir.path());
  const Result empty = RunCli("lab diagnose " + dir.str() + " --skip-bad");
  EXPECT_NE(empty.rc, 0);
  EXPECT_TRUE(Contains(empty.err, dir.str())) << empty.err;
}

// The names of a folder's entries, to check that a failed command leaves nothing behind.
std::vector<std::string> Listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// The lab decides the kind of data from the input: a catheter trial's CSV (given instead
// of its dataset folder) is never fitted with a motion model, a dataset folder never with
// one, and a motion trace never with a catheter model; each is an error naming the input,
// its kind and the model, and nothing is written.
TEST(LabCli, ModelOfTheWrongKindOfDataIsNamed) {
  TempDir dir(kTag);
  Record(dir, "--configs seed --trajectories sine --duration 1");
  fs::path trial;
  for (const auto& e : fs::directory_iterator(dir.path()))
    if (e.path().extension() == ".csv" && (trial.empty() || e.path() < trial)) trial = e.path();
  ASSERT_FALSE(trial.empty());
  const std::vector<std::string> before = Listing(dir.path());
  for (const auto& [cmd, model] : std::vector<std::pair<std::string, std::string>>{
           {"compare", ""}, {"compare", " --model seed"}, {"diagnose", " --model heartbeat:2"}}) {
    const Result r = RunCli("lab " + cmd + " " + trial.string() + model + " --json");
    EXPECT_NE(r.rc, 0) << cmd << model;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_TRUE(Contains(r.err, trial.string() + " is a catheter trial (columns t, base_cmd"))
        << r.err;
    EXPECT_TRUE(Contains(r.err, "echoservo lab compare " + dir.str() + " --model seed")) << r.err;
    if (!model.empty()) {
      EXPECT_TRUE(Contains(r.err, model.substr(9))) << r.err;
    }
  }
  const Result folder = RunCli("lab compare " + dir.str() + " --model heartbeat:2");
  EXPECT_NE(folder.rc, 0);
  EXPECT_TRUE(Contains(folder.err, dir.str() + " is a catheter dataset")) << folder.err;
  EXPECT_TRUE(Contains(folder.err, "'heartbeat:2' is a motion-trace model")) << folder.err;
  EXPECT_EQ(Listing(dir.path()), before);

  TempDir motion(std::string(kTag) + "_motion", true);
  const std::string trace = motion.str() + "/trace.csv";
  ASSERT_EQ(RunCli("sim motion --out " + trace + " --duration 4").rc, 0);
  const Result r = RunCli("lab diagnose " + trace + " --model seed+capstan_friction");
  EXPECT_NE(r.rc, 0);
  EXPECT_TRUE(Contains(r.err, trace + " is a motion trace (columns t, position")) << r.err;
  EXPECT_TRUE(Contains(r.err, "--model 'seed+capstan_friction' is a catheter model")) << r.err;
  const Result report = RunCli("lab report " + trace + " --out " + motion.str() + "/r.html");
  EXPECT_NE(report.rc, 0);
  EXPECT_TRUE(Contains(report.err, trace + " is a motion trace")) << report.err;
  EXPECT_EQ(Listing(motion.path()), std::vector<std::string>{"trace.csv"});
}

TEST(LabCli, AllBadFailsEvenWithSkipBad) {
  TempDir dir(kTag);
  Record(dir, "--configs seed --trajectories sine --duration 1");
  for (const auto& e : fs::directory_iterator(dir.path())) {
    if (e.path().extension() == ".csv") echoservo::testing::SetCsvField(e.path(), 3, 1, "oops");
  }
  const Result r = RunCli("lab compare " + dir.str() + " --skip-bad --json");
  EXPECT_NE(r.rc, 0);
  EXPECT_TRUE(Contains(r.err, "no valid trial")) << r.err;
  EXPECT_TRUE(Contains(r.err, "skipped")) << r.err;
}

}  // namespace
}  // namespace echoservo
