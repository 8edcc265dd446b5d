// EM-tracker log import (formats/em_log.h, imaging/io/em_log_import.h) on the real files in
// data/ (an NDI Aurora export, PLUS tracked sequences) and on small written files: sample
// and drop-out counts, sensor choice, units, and the errors for bad input, which must name
// the file, the line (or frame) and the field.
#include "formats/em_log.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "imaging/io/em_log_import.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"
#include "tests/test_util/trial_files.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using testing::ExpectContains;
using testing::InvalidArgumentMessage;
using testing::ReadLines;
using testing::TempDir;
using testing::WriteLines;

const fs::path kData = ECHOSERVO_DATA_DIR;
const fs::path kAurora = kData / "em_tracker" / "NDIdata_snakeravenTest_2_2_21.csv";
const fs::path kPlus = kData / "plus";

formats::EmImportOptions Sensor(const std::string& sensor) {
  formats::EmImportOptions o;
  o.sensor = sensor;
  return o;
}

bool StrictlyIncreasing(const formats::EmLog& log) {
  for (std::size_t i = 1; i < log.samples.size(); ++i) {
    if (!(log.samples[i].t_s > log.samples[i - 1].t_s)) return false;
  }
  return true;
}

// Independent count over the Aurora file's complete data rows: rows, and rows where
// sensor `s` (0-based) is written as seven zeros.
struct AuroraCounts {
  std::size_t rows = 0, zero_rows = 0;
};
AuroraCounts CountAurora(std::size_t s) {
  AuroraCounts c;
  bool data = false;
  for (const std::string& line : ReadLines(kAurora)) {
    if (line.rfind("Sample:", 0) == 0) {
      data = true;
      continue;
    }
    if (!data) continue;
    std::vector<double> v;
    std::stringstream ss(line);
    for (std::string f; std::getline(ss, f, ',');) {
      if (f.find_first_not_of(" \r") != std::string::npos) v.push_back(std::stod(f));
    }
    if (v.size() != 5 + 4 * 7) continue;  // the truncated last row
    ++c.rows;
    bool zero = true;
    for (std::size_t k = 0; k < 7; ++k) zero = zero && v[5 + 7 * s + k] == 0.0;
    c.zero_rows += zero ? 1 : 0;
  }
  return c;
}

TEST(AuroraLog, RealExportCountsSamplesAndAllZeroDropouts) {
  for (std::size_t s = 0; s < 4; ++s) {
    const formats::EmLog log = formats::ReadAuroraEmLog(kAurora, Sensor(std::to_string(s + 1)));
    const AuroraCounts expected = CountAurora(s);
    EXPECT_EQ(log.sensors, (std::vector<std::string>{"a", "b", "c", "d"}));
    EXPECT_EQ(log.sensor, log.sensors[s]);
    EXPECT_EQ(log.samples.size(), expected.rows);
    EXPECT_EQ(
        log.dropouts_by_reason.count("all zeros") ? log.dropouts_by_reason.at("all zeros") : 0u,
        expected.zero_rows);
    EXPECT_EQ(log.valid_samples(), expected.rows - expected.zero_rows);
    EXPECT_TRUE(StrictlyIncreasing(log));
    // ~21 Hz, times of day (04:15:52.821 first).
    EXPECT_NEAR(1.0 / log.MedianPeriodS(), 21.0, 3.0);
    EXPECT_NEAR(log.samples.front().t_s, 4 * 3600 + 15 * 60 + 52.821, 1e-9);
    ASSERT_EQ(log.notes.size(), 1u);  // the truncated last row
    ExpectContains(log.notes[0], "stopped mid-row");
  }
  // Sensor by letter is the same as by index; the valid positions are in mm (about 0.1 m
  // from the field generator) and never the zero sentinel.
  const formats::EmLog b = formats::ReadAuroraEmLog(kAurora, Sensor("B"));
  EXPECT_EQ(b.sensor, "b");
  for (const formats::EmSample& e : b.samples) {
    if (!e.valid) continue;
    EXPECT_GT(e.position_mm.norm(), 50.0);
    EXPECT_LT(e.position_mm.norm(), 600.0);
  }
}

TEST(AuroraLog, SeveralSensorsWithDataNeedAChoice) {
  const std::string msg =
      InvalidArgumentMessage([] { formats::ReadAuroraEmLog(kAurora, formats::EmImportOptions{}); });
  ExpectContains(msg, kAurora.string());
  ExpectContains(msg, "--sensor");
  ExpectContains(msg, "1 (a, ");
  ExpectContains(msg, "4 (d, ");
  ExpectContains(InvalidArgumentMessage([] { formats::ReadAuroraEmLog(kAurora, Sensor("e")); }),
                 "no sensor \"e\"");
  ExpectContains(InvalidArgumentMessage([] { formats::ReadAuroraEmLog(kAurora, Sensor("5")); }),
                 "no sensor \"5\"");
}

TEST(AuroraLog, InchesMustBeDeclaredAndScaleBy25_4) {
  formats::EmImportOptions in = Sensor("d");
  in.units = formats::LengthUnit::kInch;
  const formats::EmLog mm = formats::ReadAuroraEmLog(kAurora, Sensor("d"));
  const formats::EmLog inch = formats::ReadAuroraEmLog(kAurora, in);
  ASSERT_EQ(mm.samples.size(), inch.samples.size());
  EXPECT_EQ(inch.file_units, formats::LengthUnit::kInch);
  for (std::size_t i = 0; i < mm.samples.size(); ++i) {
    EXPECT_NEAR((inch.samples[i].position_mm - 25.4 * mm.samples[i].position_mm).norm(), 0.0, 1e-9);
  }
}

// A copy of the Aurora file with line `line` (1-based) replaced.
fs::path AuroraWith(const TempDir& dir, std::size_t line, const std::string& text) {
  std::vector<std::string> lines = ReadLines(kAurora);
  lines.at(line - 1) = text;
  fs::create_directories(dir.path());
  const fs::path p = dir.path() / "aurora.csv";
  WriteLines(p, lines);
  return p;
}

TEST(AuroraLog, BadRowsNameTheFileLineAndColumn) {
  const TempDir dir("em_log");
  const std::vector<std::string> lines = ReadLines(kAurora);
  // Line 10 repeats line 9 (its sample number and time).
  fs::path p = AuroraWith(dir, 10, lines[8]);
  std::string msg = InvalidArgumentMessage([&] { formats::ReadAuroraEmLog(p, Sensor("a")); });
  ExpectContains(msg, p.string() + ": line 10");
  ExpectContains(msg, "sample number");
  // The sample numbers in order but the time going back (line 8's).
  std::string back = lines[9];
  back.replace(back.find(','), std::string::npos,
               lines[7].substr(lines[7].find(',')));  // line 8's time and values
  p = AuroraWith(dir, 10, back);
  msg = InvalidArgumentMessage([&] { formats::ReadAuroraEmLog(p, Sensor("a")); });
  ExpectContains(msg, ": line 10: times must be strictly increasing");
  // NaN in a position.
  std::string nan = lines[11];
  nan.replace(nan.find("102."), 8, "nan");
  p = AuroraWith(dir, 12, nan);
  msg = InvalidArgumentMessage([&] { formats::ReadAuroraEmLog(p, Sensor("a")); });
  ExpectContains(msg, ": line 12: column 'Xa': NaN or infinity is not allowed");
  // A short row that is not the last.
  p = AuroraWith(dir, 20, "19, 4 , 15 , 53, 500,");
  msg = InvalidArgumentMessage([&] { formats::ReadAuroraEmLog(p, Sensor("a")); });
  ExpectContains(msg, ": line 20: expected 33 fields (as in the header), found 5");
  // A broken header.
  std::string header = lines[4];
  header.replace(header.find("Ya"), 2, "Yq");
  p = AuroraWith(dir, 5, header);
  msg = InvalidArgumentMessage([&] { formats::ReadAuroraEmLog(p, Sensor("a")); });
  ExpectContains(msg, ": line 5: column 7 of the Aurora header is \"Yq\"; expected 'Ya'");
}

// Found by fuzz_em_log (tests/fuzz/corpus/em_log/regression-aurora-empty-sensor-column): an
// empty first column of a sensor (",,") used to escape as std::out_of_range from
// string_view::substr instead of the reader's std::invalid_argument.
TEST(AuroraLog, EmptySensorColumnNameIsAHeaderError) {
  const TempDir dir("em_log");
  std::string header = ReadLines(kAurora)[4];
  header.replace(header.find("Xd"), 2, "");
  const fs::path p = AuroraWith(dir, 5, header);
  const std::string msg = InvalidArgumentMessage([&] { formats::ReadAuroraEmLog(p, Sensor("a")); });
  ExpectContains(msg, ": line 5: column 27 of the Aurora header is \"\"; expected 'Xa'");
}

TEST(PlusLog, WaterTankTrackerBufferHasThreeToolsAt39Hz) {
  const fs::path file = kPlus / "WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha";
  const std::string msg =
      InvalidArgumentMessage([&] { imaging::ReadEmLog(file, formats::EmImportOptions{}); });
  ExpectContains(msg, "3 tracked tools; choose one with --sensor");
  ExpectContains(msg, "StylusToTracker (801 OK)");
  for (const std::string tool : {"ProbeToTracker", "StylusToTrackerTransform"}) {
    const formats::EmLog log = imaging::ReadEmLog(file, Sensor(tool));
    EXPECT_EQ(log.format, formats::EmLogFormat::kPlus);
    EXPECT_EQ(log.sensors, (std::vector<std::string>{"ProbeToTracker", "ReferenceToTracker",
                                                     "StylusToTracker"}));
    EXPECT_EQ(log.samples.size(), 801u);
    EXPECT_EQ(log.valid_samples(), 801u);
    EXPECT_EQ(log.dropouts(), 0u);
    const double span_s = log.samples.back().t_s - log.samples.front().t_s;
    EXPECT_NEAR(800.0 / span_s, 39.0, 1.0);  // mean rate; frames come 16-30 ms apart
    EXPECT_TRUE(StrictlyIncreasing(log));
  }
  // The first probe position is the translation column of frame 0's ProbeToTracker.
  const formats::EmLog probe = imaging::ReadEmLog(file, Sensor("ProbeToTracker"));
  EXPECT_NEAR((probe.samples[0].position_mm - Eigen::Vector3d(194.556, -32.4817, 5.69268)).norm(),
              0.0, 1e-9);
  EXPECT_NEAR(probe.samples[0].t_s, 7415.679586, 1e-9);
}

TEST(PlusLog, StatusSentinelsAreDropouts) {
  // NwirePhantomFreehand: the stylus is INVALID in all 97 frames, the probe OK.
  const fs::path nwire = kPlus / "NwirePhantomFreehand.igs.mha";
  const formats::EmLog stylus = imaging::ReadEmLog(nwire, Sensor("StylusToTracker"));
  EXPECT_EQ(stylus.samples.size(), 97u);
  EXPECT_EQ(stylus.valid_samples(), 0u);
  EXPECT_EQ(stylus.dropouts_by_reason.at("INVALID"), 97u);
  EXPECT_EQ(imaging::ReadEmLog(nwire, Sensor("ProbeToTracker")).valid_samples(), 97u);
  // The NRRD syntax of the same sequence gives the same log.
  const formats::EmLog nrrd =
      imaging::ReadEmLog(kPlus / "NwirePhantomFreehand.igs.nrrd", Sensor("ProbeToTracker"));
  EXPECT_EQ(nrrd.valid_samples(), 97u);
  // TransformInterpolationTest: one INVALID probe frame (frame 7, written as identity); the
  // reference transform has no status field and counts as OK.
  const fs::path interp = kPlus / "TransformInterpolationTest.igs.mha";
  const formats::EmLog probe = imaging::ReadEmLog(interp, Sensor("ProbeToTracker"));
  EXPECT_EQ(probe.samples.size(), 500u);
  EXPECT_EQ(probe.dropouts(), 1u);
  EXPECT_EQ(probe.dropouts_by_reason.at("INVALID"), 1u);
  EXPECT_FALSE(probe.samples[7].valid);
  EXPECT_EQ(imaging::ReadEmLog(interp, Sensor("ReferenceToTracker")).valid_samples(), 500u);
  // Prostate10_tracker: status "OK " with a trailing space; its only tool is chosen alone.
  const formats::EmLog tool =
      imaging::ReadEmLog(kPlus / "Prostate10_tracker.igs.mha", formats::EmImportOptions{});
  EXPECT_EQ(tool.sensor, "ToolToTracker");
  EXPECT_EQ(tool.valid_samples(), 10u);
}

TEST(PlusLog, UnknownToolIsListed) {
  const std::string msg = InvalidArgumentMessage([] {
    imaging::ReadEmLog(kPlus / "SpinePhantomFreehand.igs.mha", Sensor("NeedleToTracker"));
  });
  ExpectContains(msg, "no tool 'NeedleToTracker'");
  ExpectContains(msg, "ProbeToTracker (21 OK)");
}

TEST(EmLogFormat, DetectedFromExtensionAndFirstLines) {
  EXPECT_EQ(formats::DetectEmLogFormat(kAurora), formats::EmLogFormat::kAurora);
  EXPECT_EQ(formats::DetectEmLogFormat(kPlus / "Prostate10_tracker.igs.mha"),
            formats::EmLogFormat::kPlus);
  EXPECT_EQ(formats::DetectEmLogFormat(kPlus / "NwirePhantomFreehand.igs.nrrd"),
            formats::EmLogFormat::kPlus);
  const TempDir dir("em_format", true);
  WriteLines(dir.path() / "em.csv", {"t_s,x_mm,y_mm,z_mm,status", "0,1,2,3,OK"});
  EXPECT_EQ(formats::DetectEmLogFormat(dir.path() / "em.csv"), formats::EmLogFormat::kSim);
  WriteLines(dir.path() / "other.csv", {"time,x,y,z", "0,1,2,3"});
  ExpectContains(
      InvalidArgumentMessage([&] { formats::DetectEmLogFormat(dir.path() / "other.csv"); }),
      "--em-format");
  ExpectContains(InvalidArgumentMessage([] { formats::ParseEmLogFormat("csv"); }), "\"csv\"");
  ExpectContains(InvalidArgumentMessage([] { formats::ParseLengthUnit("cm"); }), "mm, in");
}

TEST(SimLog, ReadsSamplesAndMissingRows) {
  const TempDir dir("em_sim", true);
  const fs::path p = dir.path() / "em.csv";
  std::vector<std::string> lines = {formats::SimEmLogHeader()};
  std::size_t missing = 0;
  for (int i = 0; i < 50; ++i) {
    formats::EmSample s{100.0 + 0.025 * i, Eigen::Vector3d(i, -i, 0.5 * i), i % 7 != 3};
    missing += s.valid ? 0 : 1;
    lines.push_back(formats::SimEmLogRow(s));
  }
  WriteLines(p, lines);
  const formats::EmLog log = imaging::ReadEmLog(p, formats::EmImportOptions{});
  EXPECT_EQ(log.format, formats::EmLogFormat::kSim);
  EXPECT_EQ(log.samples.size(), 50u);
  EXPECT_EQ(log.dropouts_by_reason.at("MISSING"), missing);
  EXPECT_EQ(log.samples[4].position_mm, Eigen::Vector3d(4, -4, 2));
  EXPECT_NEAR(log.MedianPeriodS(), 0.025, 1e-12);
}

TEST(SimLog, UnitsComeFromTheHeaderAndMustAgreeWithTheDeclaration) {
  const TempDir dir("em_sim_units", true);
  const fs::path p = dir.path() / "em.csv";
  WriteLines(p, {"t_s,x_in,y_in,z_in,status", "0,1,0,0,OK", "0.1,2,0,0,OK"});
  const formats::EmLog log = formats::ReadSimEmLog(p, formats::EmImportOptions{});
  EXPECT_EQ(log.file_units, formats::LengthUnit::kInch);
  EXPECT_NEAR(log.samples[1].position_mm.x(), 50.8, 1e-12);
  formats::EmImportOptions mm;
  mm.units = formats::LengthUnit::kMillimetre;
  const std::string msg = InvalidArgumentMessage([&] { formats::ReadSimEmLog(p, mm); });
  ExpectContains(msg, p.string());
  ExpectContains(msg, "positions are in in but mm were declared");
}

TEST(SimLog, BadRowsNameTheLine) {
  const TempDir dir("em_sim_bad", true);
  const fs::path p = dir.path() / "em.csv";
  const std::string header = formats::SimEmLogHeader();
  WriteLines(p, {header, "0,1,2,3,OK", "0.1,nan,2,3,OK"});
  ExpectContains(InvalidArgumentMessage([&] { formats::ReadSimEmLog(p, {}); }),
                 p.string() + ": line 3: column 'x_mm': NaN or infinity is not allowed");
  WriteLines(p, {header, "0,1,2,3,OK", "0.1,1,2,3,OK", "0.1,1,2,3,OK"});
  ExpectContains(InvalidArgumentMessage([&] { formats::ReadSimEmLog(p, {}); }),
                 p.string() + ": line 4: column 't_s': times must be strictly increasing");
  WriteLines(p, {header, "0,1,2,3,OK", "0.1,1,2,3,LOST"});
  ExpectContains(InvalidArgumentMessage([&] { formats::ReadSimEmLog(p, {}); }),
                 ": line 3: column 'status': \"LOST\" is not OK, MISSING");
  WriteLines(p, {"t_s,x,y,z,status", "0,1,2,3,OK"});
  ExpectContains(InvalidArgumentMessage([&] { formats::ReadSimEmLog(p, {}); }),
                 "missing position columns x_mm,y_mm,z_mm");
}

}  // namespace
}  // namespace echoservo
