// End-to-end: `echoservo lab diagnose` with effect files that cannot be used. A --candidate
// that cannot be read is skipped and reported (the diagnosis goes on, exit 0); a bad file
// in --model is an error (non-zero exit) naming the file and the JSON key, or the line and
// column of a syntax error.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using echoservo::testing::RunCli;
using echoservo::testing::RunResult;
using echoservo::testing::TempDir;

constexpr const char* kTag = "lab_open_world_cli";

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

void Write(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

// Two trials of the seed catheter (tip loads 0 and 1 N), 1 s of the 1.2 Hz sine, recorded
// once for the suite; each test writes its effect files into its own folder.
class LabOpenWorldCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dataset_ = std::make_unique<TempDir>(std::string(kTag) + "_data");
    const RunResult r = RunCli("sim record --out " + dataset_->str() +
                               " --configs seed --trajectories sine:4:1.2 --tip-loads 0,1"
                               " --duration 1");
    recorded_ = r.rc == 0;
    if (!recorded_) std::cerr << r.err;
  }
  static void TearDownTestSuite() { dataset_.reset(); }
  void SetUp() override { ASSERT_TRUE(recorded_) << "sim record failed"; }
  static fs::path data() { return dataset_->path(); }
  static inline std::unique_ptr<TempDir> dataset_;
  static inline bool recorded_ = false;
  TempDir files_{kTag, true};
};

TEST_F(LabOpenWorldCli, UnreadableCandidatesAreSkippedAndReported) {
  const fs::path missing = files_.path() / "missing.json";
  const fs::path broken = files_.path() / "broken_candidate.json";
  Write(broken, "{\"format\": \"echoservo.effect/1\",\n  \"name\": \"x\",\n}\n");
  const RunResult r = RunCli("lab diagnose " + data().string() + " --candidate @" +
                             missing.string() + " --candidate @" + broken.string() + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j.contains("skipped_candidates")) << r.out;
  const auto& skipped = j["skipped_candidates"];
  ASSERT_EQ(skipped.size(), 2u) << skipped.dump();
  const std::string first = skipped[0].get<std::string>();
  EXPECT_TRUE(Contains(first, missing.string())) << first;
  EXPECT_TRUE(Contains(first, "cannot read the effect file")) << first;
  const std::string second = skipped[1].get<std::string>();
  EXPECT_TRUE(Contains(second, broken.string())) << second;
  EXPECT_TRUE(Contains(second, "invalid JSON")) << second;
  EXPECT_TRUE(Contains(second, "line 3")) << second;
  // Both are also reported on stderr, and the diagnosis went on with the catalog's seven.
  EXPECT_TRUE(Contains(r.err, "skipped candidate @" + missing.string())) << r.err;
  EXPECT_TRUE(Contains(r.err, "skipped candidate @" + broken.string())) << r.err;
  EXPECT_EQ(j["candidates"].size(), 7u);
  EXPECT_TRUE(j["verdict"].is_string());
}

TEST_F(LabOpenWorldCli, ABadEffectFileInTheModelFailsNamingTheFileAndTheProblem) {
  // A syntax error: the file, the line and column.
  const fs::path syntax = files_.path() / "syntax.json";
  Write(syntax,
        "{\"format\": \"echoservo.effect/1\",\n  \"name\": \"bad_one\",\n  \"parameters\": "
        "[],\n  \"expressions\": {\"friction_n\": \"1\"},\n}\n");
  RunResult r =
      RunCli("lab diagnose " + data().string() + " --model seed+@" + syntax.string() + " --json");
  EXPECT_NE(r.rc, 0);
  EXPECT_TRUE(r.out.empty()) << r.out;
  EXPECT_TRUE(Contains(r.err, syntax.string())) << r.err;
  EXPECT_TRUE(Contains(r.err, "invalid JSON")) << r.err;
  EXPECT_TRUE(Contains(r.err, "line 5")) << r.err;

  // A valid JSON document with a bad expression: the file and the key.
  const fs::path key = files_.path() / "key.json";
  Write(key,
        R"({"format": "echoservo.effect/1", "name": "bad_two", "parameters": [],
            "expressions": {"friction_n": "a_n*speed_mm_s"}})");
  r = RunCli("lab diagnose " + data().string() + " --model seed+@" + key.string() + " --json");
  EXPECT_NE(r.rc, 0);
  EXPECT_TRUE(Contains(r.err, key.string() + ": expressions.friction_n")) << r.err;
  EXPECT_TRUE(Contains(r.err, "a_n")) << r.err;

  // A parameter whose bounds are inverted: parameters[0].upper.
  const fs::path bounds = files_.path() / "bounds.json";
  Write(bounds,
        R"({"format": "echoservo.effect/1", "name": "bad_three",
            "parameters": [{"name": "a_n", "unit": "N", "default": 1, "lower": 2, "upper": 0}],
            "expressions": {"friction_n": "a_n"}})");
  r = RunCli("lab diagnose " + data().string() + " --model seed+@" + bounds.string() + " --json");
  EXPECT_NE(r.rc, 0);
  EXPECT_TRUE(Contains(r.err, bounds.string() + ": parameters[0].upper")) << r.err;
}

}  // namespace
}  // namespace echoservo
