// `echoservo info` end to end: JSON for a sequence and a volume, text output, errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "imaging/io/sequence_writer.h"
#include "imaging/io/volume_io.h"
#include "tests/imaging/sequence_test_frames.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

using testing::ExpectContains;
using testing::RunCli;
using testing::ShellQuote;

const std::string kPlus = std::string(ECHOSERVO_DATA_DIR) + "/plus/";

TEST(InfoCli, SequenceJson) {
  ECHOSERVO_REQUIRES_CLI();
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
  ECHOSERVO_REQUIRES_CLI();
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
  ECHOSERVO_REQUIRES_CLI();
  auto r = RunCli("info /nonexistent/file.mha --json");
  EXPECT_NE(r.rc, 0);
  ExpectContains(r.err, "/nonexistent/file.mha");
  ExpectContains(r.err, "no such file");
}

// `info DIR`: one line per volume, sequence and RUN directory in the folder; a file that
// cannot be read is reported on its line with the reason, the others are still described,
// and the command then exits non-zero. Other files and folders are counted as ignored.
TEST(InfoCli, FolderListsEachVolumeSequenceAndRunAndErrorsPerFile) {
  ECHOSERVO_REQUIRES_CLI();
  const testing::TempDir dir("info_cli", true);
  const auto& d = dir.path();
  imaging::WriteVolume(imaging::test_frames::Frame(0), d / "a.mha", {.compress = false});
  imaging::WriteVolume(imaging::test_frames::Frame(1), d / "bad.mhd", {.compress = false});
  std::filesystem::remove(d / "bad.raw");
  {
    imaging::SequenceWriter w(d / "seq.igs.mhd");
    for (int i = 0; i < 3; ++i) w.Append(imaging::test_frames::Frame(i));
  }
  std::filesystem::create_directories(d / "run");
  std::ofstream(d / "run" / "run.json") << "{}\n";
  std::ofstream(d / "run" / "targets.csv") << "t\n";
  std::filesystem::create_directories(d / "other");
  std::ofstream(d / "notes.txt") << "not a volume\n";

  auto r = RunCli("info " + ShellQuote(d.string()) + " --json");
  EXPECT_NE(r.rc, 0);
  ExpectContains(r.err, d.string() + ": 1 of 4 entries could not be read");
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["errors"], 1);
  EXPECT_EQ(j["ignored"], 3);  // seq.igs.raw, notes.txt, other/
  ASSERT_EQ(j["entries"].size(), 4u);
  EXPECT_EQ(j["entries"][0]["file"], (d / "a.mha").string());
  EXPECT_EQ(j["entries"][0]["kind"], "volume");
  EXPECT_EQ(j["entries"][0]["dims"], nlohmann::json({24, 20, 16}));
  EXPECT_EQ(j["entries"][1]["kind"], "error");
  ExpectContains(j["entries"][1]["error"].get<std::string>(),
                 "bad.mhd: ElementDataFile 'bad.raw' not found");
  EXPECT_EQ(j["entries"][2]["kind"], "run");
  EXPECT_EQ(j["entries"][2]["files"], nlohmann::json({"run.json", "targets.csv"}));
  EXPECT_EQ(j["entries"][3]["kind"], "sequence");
  EXPECT_EQ(j["entries"][3]["frames"], 3);

  r = RunCli("info " + ShellQuote(d.string()));
  EXPECT_NE(r.rc, 0);
  ExpectContains(r.out, "4 entries (1 unreadable, 3 ignored: not a volume, sequence or RUN)");
  ExpectContains(r.out, "\na.mha  volume  1 frame  24x20x16");
  ExpectContains(r.out, "\nbad.mhd  error: ");
  ExpectContains(r.out, "\nrun  run  files: run.json, targets.csv\n");
  ExpectContains(r.out, "\nseq.igs.mhd  sequence  3 frames  24x20x16");

  std::filesystem::remove(d / "bad.mhd");
  r = RunCli("info " + ShellQuote(d.string()) + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["entries"].size(), 3u);

  r = RunCli("info " + ShellQuote((d / "other").string()));
  EXPECT_NE(r.rc, 0);
  ExpectContains(r.err, (d / "other").string() + ": no volume");
}

}  // namespace
}  // namespace echoservo
