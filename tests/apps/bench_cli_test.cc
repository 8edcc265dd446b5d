// End-to-end test of `echoservo bench detect`: the JSON's shape on a one-volume-per-class run,
// and clear errors for bad arguments.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo {
namespace {

using echoservo::testing::RunCli;
using echoservo::testing::ShellQuote;

const std::string kSpine =
    (std::filesystem::path(ECHOSERVO_DATA_DIR) / "plus" / "SpinePhantomFreehandReconstructed.mha")
        .string();

void ExpectQuantiles(const nlohmann::json& q, const std::string& what) {
  ASSERT_TRUE(q.is_object()) << what;
  for (const char* k : {"median", "p95", "count"}) EXPECT_TRUE(q.contains(k)) << what << "." << k;
}

TEST(BenchDetectCli, JsonHasThroughputAndAccuracyPerClassAndMethod) {
  ECHOSERVO_RELEASE_SUITE_ONLY("the detector accuracy harness runs under DetectorAccuracy");
  const auto r = RunCli("bench detect --volumes-per-class 1 --json --spine " + ShellQuote(kSpine));
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["volumes_per_class"], 1);
  EXPECT_EQ(j["exhaustive"], false);
  for (const char* m : {"fast", "tracking", "ransac"}) {
    ASSERT_TRUE(j["throughput_ms"].contains(m)) << m;
    EXPECT_GT(j["throughput_ms"][m]["mean"].get<double>(), 0.0) << m;
    EXPECT_GE(j["throughput_ms"][m]["volumes"].get<int>(), 1) << m;
  }
  EXPECT_FALSE(j["throughput_ms"].contains("exhaustive"));
  std::set<std::string> names;
  for (const auto& c : j["classes"]) {
    names.insert(c["name"].get<std::string>());
    EXPECT_TRUE(c["description"].is_string());
    EXPECT_GE(c["volumes"].get<int>(), 1) << c["name"];
    EXPECT_TRUE(c["agreement"].is_null());  // no --exhaustive
    std::set<std::string> methods;
    for (const auto& m : c["methods"]) {
      methods.insert(m["method"].get<std::string>());
      for (const char* k :
           {"volumes", "detected", "detection_rate", "false_detections", "errors", "mean_ms"})
        EXPECT_TRUE(m[k].is_number()) << c["name"] << " " << m["method"] << " " << k;
      for (const char* k : {"angle_deg", "offset_mm", "tip_mm", "target_mm"})
        ExpectQuantiles(m[k], k);
    }
    EXPECT_TRUE(methods.count("fast") && methods.count("ransac")) << c["name"];
    EXPECT_EQ(methods.count("tracking"), c["catheter"].get<bool>() ? 1u : 0u) << c["name"];
  }
  for (const char* n :
       {"water_tank", "no_reverberation", "speckle_clutter", "shadowing", "wide_poses",
        "sound_speed", "free_annulus", "free_tank", "free_clutter", "spine_phantom"})
    EXPECT_TRUE(names.count(n)) << n;
  EXPECT_TRUE(j["agreement"].is_null());
  EXPECT_TRUE(j["skipped"].is_array());
}

TEST(BenchDetectCli, BadArgumentsFailWithAClearMessage) {
  auto r = RunCli("bench detect --volumes-per-class 0");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--volumes-per-class"), std::string::npos) << r.err;
  r = RunCli("bench detect --volumes-per-class many");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--volumes-per-class"), std::string::npos) << r.err;
  r = RunCli("bench detect --classes water_tank,no_such_class");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("no_such_class"), std::string::npos) << r.err;
  r = RunCli("bench detect --spine /no/such/volume.mha");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("/no/such/volume.mha"), std::string::npos) << r.err;
  r = RunCli("bench");
  EXPECT_NE(r.rc, 0);
}

}  // namespace
}  // namespace echoservo
