#include "formats/trial_io.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace echoservo::formats {
namespace {

namespace fs = std::filesystem;

constexpr const char* kGoodJson = R"({
  "sheath_id_mm": 1.6,
  "guidewire_od_mm": 0.8,
  "bends": [{"angle_deg": 90, "radius_mm": 50}, {"angle_deg": 90.0, "radius_mm": 25.0}],
  "tip_load_n": 0.5
})";

constexpr const char* kGoodCsv =
    "t,base_cmd,base,tip,force\n"
    "0,0,0,0,0\n"
    "0.001,0.01,0.009,0.002,0.05\n"
    "0.002,0.02,0.019,0.006,0.1\n";

// A fresh, uniquely named folder under the system temp directory, removed afterwards.
class TempDir {
 public:
  TempDir() {
    static std::atomic<unsigned> counter{0};
    std::random_device rd;
    const auto stamp = std::chrono::steady_clock::now().time_since_epoch().count();
    path_ = fs::temp_directory_path() / ("echoservo_trial_io_" + std::to_string(rd()) + "_" +
                                         std::to_string(stamp) + "_" + std::to_string(counter++));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

void WriteText(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  ASSERT_TRUE(out) << p;
  out << text;
}

std::string ReadText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

Trial SampleTrial() {
  Trial t;
  t.name = "sample_trial";
  t.config = CatheterConfig::SeedEvaluation();
  t.config.tip_load_n = 0.25;
  std::mt19937_64 rng(1234);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  const std::size_t n = 500;
  for (std::size_t i = 0; i < n; ++i) {
    t.t_s.push_back(static_cast<double>(i) * 1e-3 + u(rng) * 1e-9);  // not representable in %.6f
    t.base_cmd_mm.push_back(u(rng));
    t.base_mm.push_back(u(rng) / 3.0);
    t.tip_mm.push_back(std::sin(u(rng)) * 1e-7);
    t.force_n.push_back(u(rng) * 1e-300);  // tiny values must survive too
  }
  t.base_cmd_mm[1] = 0.1;  // a classic non-terminating binary fraction
  t.tip_mm[2] = -0.0;
  t.force_n[3] = std::numeric_limits<double>::max();
  t.force_n[4] = std::numeric_limits<double>::denorm_min();
  t.extra_names = {"motor_current_a", "z_extra"};
  t.extra_columns.resize(2);
  for (std::size_t i = 0; i < n; ++i) {
    t.extra_columns[0].push_back(u(rng) * 1e5);
    t.extra_columns[1].push_back(1.0 / 3.0 + static_cast<double>(i));
  }
  t.meta_json = R"({"simulator":"echoservo","run":{"seed":7,"notes":["a","b"]},"gain":0.1})";
  return t;
}

// Runs `fn`, expects a TrialFormatError, and checks that its message contains every needle.
void ExpectTrialError(const std::function<void()>& fn, const std::vector<std::string>& needles) {
  try {
    fn();
    ADD_FAILURE() << "expected TrialFormatError";
  } catch (const TrialFormatError& e) {
    const std::string msg = e.what();
    for (const std::string& needle : needles) {
      EXPECT_NE(msg.find(needle), std::string::npos)
          << "message: " << msg << "\nmissing: " << needle;
    }
  }
}

// Writes `csv` and `json` as `<dir>/<stem>.csv/.json` and expects ReadTrial to fail mentioning
// the offending file name plus `needles`.
void ExpectReadError(const TempDir& dir, const std::string& csv, const std::string& json,
                     const std::string& bad_file, const std::vector<std::string>& needles) {
  WriteText(dir.path() / "trial_x.csv", csv);
  WriteText(dir.path() / "trial_x.json", json);
  std::vector<std::string> all = needles;
  all.push_back(bad_file);
  ExpectTrialError([&] { ReadTrial(dir.path() / "trial_x.csv"); }, all);
}

void ExpectCsvError(const std::string& csv, const std::vector<std::string>& needles) {
  TempDir dir;
  ExpectReadError(dir, csv, kGoodJson, "trial_x.csv", needles);
}

void ExpectJsonError(const std::string& json, const std::vector<std::string>& needles) {
  TempDir dir;
  ExpectReadError(dir, kGoodCsv, json, "trial_x.json", needles);
}

// ------------------------------------------------------------------ happy paths

TEST(TrialIo, RoundTripIsExact) {
  TempDir dir;
  const Trial in = SampleTrial();
  WriteTrial(dir.path() / "nested" / "out", in);
  const Trial out = ReadTrial(dir.path() / "nested" / "out" / "sample_trial.csv");
  EXPECT_EQ(out.name, in.name);
  EXPECT_EQ(out.t_s, in.t_s);
  EXPECT_EQ(out.base_cmd_mm, in.base_cmd_mm);
  EXPECT_EQ(out.base_mm, in.base_mm);
  EXPECT_EQ(out.tip_mm, in.tip_mm);
  EXPECT_TRUE(std::signbit(out.tip_mm[2]));
  EXPECT_EQ(out.force_n, in.force_n);
  EXPECT_EQ(out.extra_names, in.extra_names);
  EXPECT_EQ(out.extra_columns, in.extra_columns);
  EXPECT_EQ(out.meta_json, in.meta_json);  // key order kept
  EXPECT_EQ(out.config.sheath_id_mm, in.config.sheath_id_mm);
  EXPECT_EQ(out.config.guidewire_od_mm, in.config.guidewire_od_mm);
  EXPECT_EQ(out.config.tip_load_n, in.config.tip_load_n);
  ASSERT_EQ(out.config.bends.size(), in.config.bends.size());
  for (std::size_t i = 0; i < in.config.bends.size(); ++i) {
    EXPECT_EQ(out.config.bends[i].angle_deg, in.config.bends[i].angle_deg);
    EXPECT_EQ(out.config.bends[i].radius_mm, in.config.bends[i].radius_mm);
  }
  EXPECT_TRUE(out.warnings.empty());

  const std::string csv = ReadText(dir.path() / "nested" / "out" / "sample_trial.csv");
  EXPECT_EQ(csv.rfind("t,base_cmd,base,tip,force,motor_current_a,z_extra\n", 0), 0u)
      << csv.substr(0, 80);
  EXPECT_FALSE(fs::exists(dir.path() / "nested" / "out" / "sample_trial.csv.tmp"));
}

TEST(TrialIo, RewriteOfReadTrialIsIdentical) {
  TempDir dir;
  WriteTrial(dir.path() / "a", SampleTrial());
  WriteTrial(dir.path() / "b", ReadTrial(dir.path() / "a" / "sample_trial.csv"));
  EXPECT_EQ(ReadText(dir.path() / "a" / "sample_trial.csv"),
            ReadText(dir.path() / "b" / "sample_trial.csv"));
  EXPECT_EQ(ReadText(dir.path() / "a" / "sample_trial.json"),
            ReadText(dir.path() / "b" / "sample_trial.json"));
}

TEST(TrialIo, EmptyMetaIsOmittedAndReadBackAsEmptyObject) {
  TempDir dir;
  Trial in = SampleTrial();
  in.meta_json = "{}";
  WriteTrial(dir.path(), in);
  EXPECT_EQ(ReadText(dir.path() / "sample_trial.json").find("meta"), std::string::npos);
  EXPECT_EQ(ReadTrial(dir.path() / "sample_trial.csv").meta_json, "{}");
}

TEST(TrialIo, ExtraColumnsPreservedInFileOrder) {
  TempDir dir;
  WriteText(dir.path() / "x.csv",
            "zeta,t,base_cmd,alpha,base,tip,force,mid\n"
            "9,0,1,2,3,4,5,6\n"
            "8,0.001,1.5,2.5,3.5,4.5,5.5,6.5\n");
  WriteText(dir.path() / "x.json", kGoodJson);
  const Trial t = ReadTrial(dir.path() / "x.csv");
  EXPECT_EQ(t.extra_names, (std::vector<std::string>{"zeta", "alpha", "mid"}));
  ASSERT_EQ(t.extra_columns.size(), 3u);
  EXPECT_EQ(t.extra_columns[0], (std::vector<double>{9, 8}));
  EXPECT_EQ(t.extra_columns[1], (std::vector<double>{2, 2.5}));
  EXPECT_EQ(t.extra_columns[2], (std::vector<double>{6, 6.5}));
  EXPECT_EQ(t.base_cmd_mm, (std::vector<double>{1, 1.5}));

  // And they survive a write/read cycle.
  WriteTrial(dir.path() / "copy", t);
  const Trial back = ReadTrial(dir.path() / "copy" / "x.csv");
  EXPECT_EQ(back.extra_names, t.extra_names);
  EXPECT_EQ(back.extra_columns, t.extra_columns);
}

TEST(TrialIo, ColumnOrderDoesNotMatter) {
  TempDir dir;
  WriteText(dir.path() / "a.csv", kGoodCsv);
  WriteText(dir.path() / "a.json", kGoodJson);
  WriteText(dir.path() / "b.csv",
            "force,tip,base,base_cmd,t\n"
            "0,0,0,0,0\n"
            "0.05,0.002,0.009,0.01,0.001\n"
            "0.1,0.006,0.019,0.02,0.002\n");
  WriteText(dir.path() / "b.json", kGoodJson);
  const Trial a = ReadTrial(dir.path() / "a.csv");
  const Trial b = ReadTrial(dir.path() / "b.csv");
  EXPECT_EQ(a.t_s, b.t_s);
  EXPECT_EQ(a.base_cmd_mm, b.base_cmd_mm);
  EXPECT_EQ(a.base_mm, b.base_mm);
  EXPECT_EQ(a.tip_mm, b.tip_mm);
  EXPECT_EQ(a.force_n, b.force_n);
  EXPECT_TRUE(b.extra_names.empty());
  EXPECT_EQ(b.t_s, (std::vector<double>{0, 0.001, 0.002}));
  EXPECT_EQ(b.force_n, (std::vector<double>{0, 0.05, 0.1}));
}

TEST(TrialIo, AcceptsCrlfBomWhitespaceAndTrailingEmptyLines) {
  TempDir dir;
  WriteText(dir.path() / "w.csv",
            "\xEF\xBB\xBF t , base_cmd,base ,\ttip,force\r\n"
            " 0 , 0,0,0 ,0\r\n"
            "1e-3,+0.5,-0.25, 0.125 ,2E-1\r\n"
            "\r\n"
            "   \r\n"
            "\n");
  WriteText(dir.path() / "w.json", "\xEF\xBB\xBF" + std::string(kGoodJson) + "\r\n");
  const Trial t = ReadTrial(dir.path() / "w.csv");
  EXPECT_EQ(t.name, "w");
  EXPECT_EQ(t.t_s, (std::vector<double>{0, 0.001}));
  EXPECT_EQ(t.base_cmd_mm, (std::vector<double>{0, 0.5}));
  EXPECT_EQ(t.base_mm, (std::vector<double>{0, -0.25}));
  EXPECT_EQ(t.tip_mm, (std::vector<double>{0, 0.125}));
  EXPECT_EQ(t.force_n, (std::vector<double>{0, 0.2}));
  EXPECT_TRUE(t.extra_names.empty());
  EXPECT_EQ(t.config.tip_load_n, 0.5);
  ASSERT_EQ(t.config.bends.size(), 2u);
  EXPECT_EQ(t.config.bends[1].radius_mm, 25.0);
}

TEST(TrialIo, UnknownTopLevelJsonKeysWarn) {
  TempDir dir;
  WriteText(dir.path() / "u.csv", kGoodCsv);
  WriteText(dir.path() / "u.json", R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "bends": [],
      "tip_load_n": 0, "simulator_version": "3.1", "meta": {"b": 1, "a": [true, null]}})");
  const Trial t = ReadTrial(dir.path() / "u.csv");
  ASSERT_EQ(t.warnings.size(), 1u);
  EXPECT_NE(t.warnings[0].find("u.json"), std::string::npos) << t.warnings[0];
  EXPECT_NE(t.warnings[0].find("simulator_version"), std::string::npos) << t.warnings[0];
  EXPECT_EQ(t.meta_json, R"({"b":1,"a":[true,null]})");
  EXPECT_TRUE(t.config.bends.empty());
}

TEST(TrialDataset, ReadsPairsSortedByName) {
  TempDir dir;
  Trial t = SampleTrial();
  for (const char* name : {"trial_b", "trial_a", "trial_c"}) {
    t.name = name;
    WriteTrial(dir.path(), t);
  }
  WriteText(dir.path() / "README.txt", "not a trial");
  WriteText(dir.path() / "orphan.json", kGoodJson);  // a JSON without a CSV is ignored
  const std::vector<Trial> trials = ReadDataset(dir.path());
  ASSERT_EQ(trials.size(), 3u);
  EXPECT_EQ(trials[0].name, "trial_a");
  EXPECT_EQ(trials[1].name, "trial_b");
  EXPECT_EQ(trials[2].name, "trial_c");
  EXPECT_EQ(trials[2].t_s, t.t_s);
}

// ---------------------------------------------------------------- CSV errors

TEST(TrialIoError, MissingCsvFile) {
  TempDir dir;
  ExpectTrialError([&] { ReadTrial(dir.path() / "nope.csv"); }, {"nope.csv", "not found"});
}

TEST(TrialIoError, MissingSiblingJson) {
  TempDir dir;
  WriteText(dir.path() / "lonely.csv", kGoodCsv);
  ExpectTrialError([&] { ReadTrial(dir.path() / "lonely.csv"); },
                   {"lonely.json", "lonely.csv", "not found"});
}

TEST(TrialIoError, EmptyFile) {
  ExpectCsvError("", {"empty file"});
  ExpectCsvError("\xEF\xBB\xBF\r\n\n  \n", {"empty file"});
}

TEST(TrialIoError, MissingRequiredColumn) {
  ExpectCsvError("t,base_cmd,base,force\n0,0,0,0\n1,1,1,1\n",
                 {"line 1", "missing required column 'tip'"});
  ExpectCsvError("time,base_cmd,base,tip,force\n0,0,0,0,0\n1,1,1,1,1\n", {"line 1", "'t'"});
  ExpectCsvError("t,tip\n0,0\n1,1\n",
                 {"line 1", "missing required columns 'base_cmd', 'base', 'force'"});
}

TEST(TrialIoError, DuplicateColumnName) {
  ExpectCsvError("t,base_cmd,base,tip,force,tip\n0,0,0,0,0,0\n1,1,1,1,1,1\n",
                 {"line 1", "duplicate column", "\"tip\""});
  ExpectCsvError("t,base_cmd,,base,tip,force\n", {"line 1", "empty name"});
}

TEST(TrialIoError, WrongFieldCount) {
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n0.001,0,0,0\n",
                 {"line 3", "expected 5 fields", "found 4"});
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0,\n0.001,0,0,0,0\n", {"line 2", "found 6"});
}

TEST(TrialIoError, FieldNotANumber) {
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n0.001,0,abc,0,0\n",
                 {"line 3", "column 'base'", "not a number", "\"abc\""});
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n0.001,0,0,0,\n",
                 {"line 3", "column 'force'", "\"\""});
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n0.001,0,0,1.5.2,0\n",
                 {"line 3", "\"1.5.2\""});
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n0.001,0,0,0x10,0\n",
                 {"line 3", "\"0x10\""});
  // Long text is quoted but truncated.
  const std::string junk(5000, 'q');
  TempDir dir;
  WriteText(dir.path() / "long.csv",
            "t,base_cmd,base,tip,force\n0,0,0,0,0\n1," + junk + ",0,0,0\n");
  WriteText(dir.path() / "long.json", kGoodJson);
  try {
    ReadTrial(dir.path() / "long.csv");
    ADD_FAILURE() << "expected TrialFormatError";
  } catch (const TrialFormatError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("long.csv"), std::string::npos) << msg;
    EXPECT_NE(msg.find("line 3"), std::string::npos) << msg;
    EXPECT_NE(msg.find("\"qqqq"), std::string::npos) << msg;
    EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
    EXPECT_LT(msg.size(), 300u) << msg;
  }
}

TEST(TrialIoError, HugeHeaderAndLinesAreHandledWithoutBlowingUp) {
  std::string header = "t,base_cmd,base,tip,force";
  for (int i = 0; i < 200000; ++i) header += ",c" + std::to_string(i);
  ExpectCsvError(header + "\n0,0,0\n", {"line 2", "expected 200005 fields", "found 3"});
  ExpectCsvError(header + ",c77\n", {"line 1", "duplicate column name \"c77\""});
  ExpectCsvError("t,base_cmd,base,tip,force\n" + std::string(1000000, ',') + "\n",
                 {"line 2", "expected 5 fields", "found 1000001"});
}

TEST(TrialIoError, NanOrInfinity) {
  for (const char* bad : {"nan", "NaN", "inf", "-inf", "Infinity"}) {
    ExpectCsvError(std::string("t,base_cmd,base,tip,force\n0,0,0,0,0\n0.001,0,0,") + bad + ",0\n",
                   {"line 3", "column 'tip'", "NaN or infinity", bad});
  }
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n0.001,1e999,0,0,0\n",
                 {"line 3", "out of the range", "1e999"});
}

TEST(TrialIoError, TimesNotStrictlyIncreasing) {
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n0.001,0,0,0,0\n0.001,0,0,0,0\n",
                 {"line 4", "column 't'", "strictly increasing", "on line 3"});
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n-0.001,0,0,0,0\n",
                 {"line 3", "strictly increasing"});
}

TEST(TrialIoError, TooFewSamples) {
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n", {"1 sample", "at least 2"});
  ExpectCsvError("t,base_cmd,base,tip,force\n\n\n", {"0 sample", "at least 2"});
}

TEST(TrialIoError, BlankLineInsideData) {
  ExpectCsvError("t,base_cmd,base,tip,force\n0,0,0,0,0\n\n0.001,0,0,0,0\n",
                 {"line 3", "empty line"});
}

// --------------------------------------------------------------- JSON errors

TEST(TrialIoError, JsonParseError) {
  ExpectJsonError(R"({"sheath_id_mm": 1.6, "guidewire_od_mm": })",
                  {"JSON parse error", "parse_error"});
  ExpectJsonError("", {"JSON parse error"});
  ExpectJsonError(std::string(1000, '[') + std::string(1000, ']'), {"nested deeper"});
}

TEST(TrialIoError, JsonWrongTypes) {
  ExpectJsonError("[1, 2]", {"top level must be a JSON object", "array"});
  ExpectJsonError(
      R"({"sheath_id_mm": "1.6", "guidewire_od_mm": 0.8, "bends": [], "tip_load_n": 0})",
      {"'sheath_id_mm'", "must be a number", "string"});
  ExpectJsonError(R"({"sheath_id_mm": 1.6, "guidewire_od_mm": true, "bends": [], "tip_load_n": 0})",
                  {"'guidewire_od_mm'", "must be a number", "boolean"});
  ExpectJsonError(
      R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "bends": [], "tip_load_n": null})",
      {"'tip_load_n'", "must be a number", "null"});
  ExpectJsonError(
      R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "bends": [], "tip_load_n": 0, "meta": 3})",
      {"'meta'", "must be an object"});
  ExpectJsonError(
      R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "bends": [[90, 5]], "tip_load_n": 0})",
      {"'bends[0]'", "must be an object"});
  ExpectJsonError(
      R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "bends": [{"angle_deg": 90, "radius_mm": "5"}],
          "tip_load_n": 0})",
      {"'bends[0].radius_mm'", "must be a number"});
}

TEST(TrialIoError, JsonMissingKey) {
  ExpectJsonError(R"({"sheath_id_mm": 1.6, "bends": [], "tip_load_n": 0})",
                  {"missing key 'guidewire_od_mm'"});
  ExpectJsonError(R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "tip_load_n": 0})",
                  {"missing key 'bends'"});
  ExpectJsonError(
      R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "bends": [{"angle_deg": 90}], "tip_load_n": 0})",
      {"missing key 'bends[0].radius_mm'"});
}

TEST(TrialIoError, BendsNotAList) {
  ExpectJsonError(
      R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "bends": {"angle_deg": 90, "radius_mm": 5}, "tip_load_n": 0})",
      {"'bends'", "must be a list", "object"});
}

TEST(TrialIoError, UnknownBendKey) {
  ExpectJsonError(
      R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "tip_load_n": 0,
          "bends": [{"angle_deg": 90, "radius_mm": 5}, {"angle_deg": 90, "radius_mm": 5, "radius_m": 0.005}]})",
      {"'bends[1].radius_m'", "unknown"});
}

TEST(TrialIoError, NonPhysicalGeometry) {
  ExpectJsonError(R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 1.7, "bends": [], "tip_load_n": 0})",
                  {"guidewire_od_mm", "smaller than sheath_id_mm"});
  ExpectJsonError(
      R"({"sheath_id_mm": 1.6, "guidewire_od_mm": 0.8, "bends": [{"angle_deg": 90, "radius_mm": -5}], "tip_load_n": 0})",
      {"bends[0].radius_mm"});
}

// ------------------------------------------------------------- dataset errors

TEST(TrialDatasetError, MissingFolder) {
  TempDir dir;
  ExpectTrialError([&] { ReadDataset(dir.path() / "absent_folder"); },
                   {"absent_folder", "not found"});
}

TEST(TrialDatasetError, NotADirectory) {
  TempDir dir;
  WriteText(dir.path() / "plain_file", "x");
  ExpectTrialError([&] { ReadDataset(dir.path() / "plain_file"); },
                   {"plain_file", "not a directory"});
}

TEST(TrialDatasetError, NoTrials) {
  TempDir dir;
  WriteText(dir.path() / "only.json", kGoodJson);
  ExpectTrialError([&] { ReadDataset(dir.path()); }, {dir.path().filename().string(), "no trials"});
}

TEST(TrialDatasetError, CsvWithoutSiblingJson) {
  TempDir dir;
  WriteText(dir.path() / "a.csv", kGoodCsv);
  WriteText(dir.path() / "a.json", kGoodJson);
  WriteText(dir.path() / "b_orphan.csv", kGoodCsv);
  ExpectTrialError([&] { ReadDataset(dir.path()); },
                   {"b_orphan.csv", "b_orphan.json", "no sibling JSON"});
}

TEST(TrialDatasetError, InvalidTrialNamesItsFile) {
  TempDir dir;
  WriteText(dir.path() / "a.csv", kGoodCsv);
  WriteText(dir.path() / "a.json", kGoodJson);
  WriteText(dir.path() / "b.csv", "t,base_cmd,base,tip,force\n0,0,0,0,0\n0,0,0,0,0\n");
  WriteText(dir.path() / "b.json", kGoodJson);
  ExpectTrialError([&] { ReadDataset(dir.path()); }, {"b.csv", "line 3", "strictly increasing"});
}

// -------------------------------------------------------------- writer errors

TEST(TrialWriteError, RejectsInvalidTrials) {
  TempDir dir;
  const auto expect_rejected = [&](const Trial& t, const std::vector<std::string>& needles) {
    ExpectTrialError([&] { WriteTrial(dir.path() / "out", t); }, needles);
    EXPECT_FALSE(fs::exists(dir.path() / "out" / "sample_trial.csv"));
    EXPECT_FALSE(fs::exists(dir.path() / "out" / "sample_trial.json"));
  };
  Trial t = SampleTrial();
  t.tip_mm.pop_back();
  expect_rejected(t, {"sample_trial.csv", "column 'tip'", "499 samples"});

  t = SampleTrial();
  t.extra_columns[1].push_back(1.0);
  expect_rejected(t, {"sample_trial.csv", "column 'z_extra'"});

  t = SampleTrial();
  t.extra_names.pop_back();
  expect_rejected(t, {"sample_trial.csv", "extra column"});

  t = SampleTrial();
  t.extra_names[0] = "base";
  expect_rejected(t, {"sample_trial.csv", "duplicate column name \"base\""});

  t = SampleTrial();
  t.extra_names[0] = "a,b";
  expect_rejected(t, {"sample_trial.csv", "\"a,b\""});

  t = SampleTrial();
  t.force_n[10] = std::nan("");
  expect_rejected(t, {"sample_trial.csv", "column 'force' sample 10", "not finite"});

  t = SampleTrial();
  t.extra_columns[0][3] = -INFINITY;
  expect_rejected(t, {"sample_trial.csv", "column 'motor_current_a' sample 3"});

  t = SampleTrial();
  t.t_s[7] = t.t_s[6];
  expect_rejected(t, {"sample_trial.csv", "strictly increasing at sample 7"});

  t = SampleTrial();
  t.t_s.resize(1);
  t.base_cmd_mm.resize(1);
  t.base_mm.resize(1);
  t.tip_mm.resize(1);
  t.force_n.resize(1);
  t.extra_columns[0].resize(1);
  t.extra_columns[1].resize(1);
  expect_rejected(t, {"sample_trial.csv", "at least 2"});

  t = SampleTrial();
  t.config.sheath_id_mm = 0.5;
  expect_rejected(t, {"sample_trial.json", "guidewire_od_mm"});

  t = SampleTrial();
  t.meta_json = "[1]";
  expect_rejected(t, {"sample_trial.json", "meta_json must be a JSON object"});

  t = SampleTrial();
  t.meta_json = "{oops";
  expect_rejected(t, {"sample_trial.json", "meta_json is not valid JSON"});

  t = SampleTrial();
  t.name = "../escape";
  expect_rejected(t, {"invalid trial name", "\"../escape\""});

  t = SampleTrial();
  t.name = "";
  expect_rejected(t, {"invalid trial name"});
}

}  // namespace
}  // namespace echoservo::formats
