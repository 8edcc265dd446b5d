// `echoservo info` end to end: JSON for a sequence and a volume, text output, errors.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/expect_error.h"

namespace echoservo {
namespace {

using testing::ExpectContains;
using testing::RunCli;
using testing::ShellQuote;

const std::string kPlus = std::string(ECHOSERVO_DATA_DIR) + "/plus/";

TEST(InfoCli, SequenceJson) {
  const auto r = RunCli("info " + ShellQuote(kPlus + "NwirePhantomFreehand.igs.mha") + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frames"], 97);
  EXPECT_EQ(j["dims"], nlohmann::json({820, 616, 1}));
  EXPECT_EQ(j["spacing"], nlohmann::json({1.0, 1.0, 1.0}));
  EXPECT_EQ(j["element_type"], "MET_UCHAR");
  EXPECT_EQ(j["compressed"], true);
  EXPECT_NE(
      std::find(j["frame_fields"].begin(), j["frame_fields"].end(), "ProbeToTrackerTransform"),
      j["frame_fields"].end());
  EXPECT_DOUBLE_EQ(j["timestamp_range"][0].get<double>(), 345.627957);
}

TEST(InfoCli, TrackerOnlyAndVolume) {
  auto r = RunCli("info " +
                  ShellQuote(kPlus + "WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha") +
                  " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frames"], 801);
  EXPECT_EQ(j["dims"], nlohmann::json({0, 0, 0}));
  r = RunCli("info " + ShellQuote(kPlus + "SpinePhantomFreehandReconstructed.mha") + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frames"], 1);
  EXPECT_EQ(j["dims"], nlohmann::json({147, 106, 104}));
  EXPECT_EQ(j["spacing"], nlohmann::json({0.5, 0.5, 0.5}));
  EXPECT_EQ(j["origin"], nlohmann::json({-74.5217, 165.573, 29.072}));
  r = RunCli("info " + ShellQuote(kPlus + "SpinePhantomFreehand.igs.mha"));
  ASSERT_EQ(r.rc, 0) << r.err;
  ExpectContains(r.out, "frames:        21");
  ExpectContains(r.out, "820 x 616 x 1");
}

TEST(InfoCli, ErrorsNameTheFile) {
  auto r = RunCli("info /nonexistent/file.mha --json");
  EXPECT_NE(r.rc, 0);
  ExpectContains(r.err, "/nonexistent/file.mha");
  ExpectContains(r.err, "no such file");
}

}  // namespace
}  // namespace echoservo
