// Reader and writer of the trial format (docs/trial_format.md).
#include "formats/trial_io.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_set>
#include <utility>
#include <vector>

#include "formats/csv_table.h"

namespace echoservo::formats {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;  // keeps key order, so `meta` stays as written

constexpr std::array<const char*, 5> kRequiredColumns = {"t", "base_cmd", "base", "tip", "force"};
constexpr int kMaxJsonDepth = 64;  // guards the recursive JSON serialiser
constexpr std::size_t kMinSamples = 2;

using csv::AppendNumber;
using csv::FormatNumber;
using csv::Quote;
using csv::Trim;

void RequireRegularFile(const fs::path& path, const std::string& what) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) FailFile<TrialFormatError>(path, what + " not found");
  if (!fs::is_regular_file(st)) FailFile<TrialFormatError>(path, what + " is not a regular file");
}

fs::path SiblingJson(const fs::path& csv_path) {
  fs::path json = csv_path;
  json.replace_extension(".json");
  return json;
}

// ----------------------------------------------------------------------------- CSV

CsvTable ReadCsv(const fs::path& path) {
  CsvTableSpec spec;
  spec.required = {kRequiredColumns.begin(), kRequiredColumns.end()};
  spec.required_hint = "(required: t,base_cmd,base,tip,force, in any order)";
  spec.min_rows = kMinSamples;
  spec.what = "a trial";
  try {
    return ReadCsvTable(path, spec);
  } catch (const CsvFormatError& e) {
    throw TrialFormatError(e.what());
  }
}

// ---------------------------------------------------------------------------- JSON

std::string ReadWholeFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) FailFile<TrialFormatError>(path, "cannot open file for reading");
  std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) FailFile<TrialFormatError>(path, "read error");
  return text;
}

Json ParseJsonText(const fs::path& path, const std::string& text) {
  // Reject absurd nesting before it reaches the (recursive) serialiser.
  const Json::parser_callback_t depth_guard = [&path](int depth, Json::parse_event_t, Json&) {
    if (depth > kMaxJsonDepth) {
      FailFile<TrialFormatError>(
          path, "JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
    }
    return true;
  };
  try {
    return Json::parse(text, depth_guard);
  } catch (const Json::exception& e) {
    FailFile<TrialFormatError>(path, std::string("JSON parse error: ") + e.what());
  }
}

double RequireNumber(const fs::path& path, const Json& obj, const std::string& key,
                     const std::string& display) {
  const auto it = obj.find(key);
  if (it == obj.end()) FailFile<TrialFormatError>(path, "missing key '" + display + "'");
  if (!it->is_number()) {
    FailFile<TrialFormatError>(
        path, "key '" + display + "' must be a number, got " + std::string(it->type_name()));
  }
  return it->get<double>();
}

bool IsGeometryKey(const std::string& k) {
  return k == "sheath_id_mm" || k == "guidewire_od_mm" || k == "bends" || k == "tip_load_n";
}

// The catheter geometry keys of a trial JSON or a catheter configuration file.
CatheterConfig ParseGeometry(const fs::path& path, const Json& j) {
  if (!j.is_object()) {
    FailFile<TrialFormatError>(
        path, "the top level must be a JSON object, got " + std::string(j.type_name()));
  }
  CatheterConfig cfg;
  cfg.sheath_id_mm = RequireNumber(path, j, "sheath_id_mm", "sheath_id_mm");
  cfg.guidewire_od_mm = RequireNumber(path, j, "guidewire_od_mm", "guidewire_od_mm");
  cfg.tip_load_n = RequireNumber(path, j, "tip_load_n", "tip_load_n");

  const auto bends = j.find("bends");
  if (bends == j.end()) FailFile<TrialFormatError>(path, "missing key 'bends'");
  if (!bends->is_array()) {
    FailFile<TrialFormatError>(
        path, "key 'bends' must be a list, got " + std::string(bends->type_name()));
  }
  for (std::size_t i = 0; i < bends->size(); ++i) {
    const Json& b = (*bends)[i];
    const std::string key = "bends[" + std::to_string(i) + "]";
    if (!b.is_object()) {
      FailFile<TrialFormatError>(
          path, "key '" + key + "' must be an object, got " + std::string(b.type_name()));
    }
    for (const auto& [k, v] : b.items()) {
      if (k != "angle_deg" && k != "radius_mm") {
        FailFile<TrialFormatError>(
            path,
            "key '" + key + "." + k + "' is unknown (a bend has only angle_deg and radius_mm)");
      }
    }
    Bend bend;
    bend.angle_deg = RequireNumber(path, b, "angle_deg", key + ".angle_deg");
    bend.radius_mm = RequireNumber(path, b, "radius_mm", key + ".radius_mm");
    cfg.bends.push_back(bend);
  }
  try {
    cfg.Validate(path.string());
  } catch (const std::invalid_argument& e) {
    throw TrialFormatError(e.what());
  }
  return cfg;
}

void ReadJson(const fs::path& path, Trial& trial) {
  const Json j = ParseJsonText(path, ReadWholeFile(path));
  trial.config = ParseGeometry(path, j);
  trial.meta_json = "{}";
  if (const auto meta = j.find("meta"); meta != j.end()) {
    if (!meta->is_object()) {
      FailFile<TrialFormatError>(
          path, "key 'meta' must be an object, got " + std::string(meta->type_name()));
    }
    trial.meta_json = meta->dump();
  }
  for (const auto& [k, v] : j.items()) {
    if (!IsGeometryKey(k) && k != "meta") {
      trial.warnings.push_back(path.string() + ": ignoring unknown key '" + k + "'");
    }
  }
}

// -------------------------------------------------------------------------- writer

[[noreturn]] void FailWrite(const fs::path& file, const std::string& why) {
  throw TrialFormatError(file.string() + ": cannot write trial: " + why);
}

void ValidateForWrite(const fs::path& csv_path, const fs::path& json_path, const Trial& trial) {
  const std::size_t n = trial.t_s.size();
  const std::pair<const char*, const std::vector<double>*> required[] = {
      {"t", &trial.t_s},
      {"base_cmd", &trial.base_cmd_mm},
      {"base", &trial.base_mm},
      {"tip", &trial.tip_mm},
      {"force", &trial.force_n}};
  if (trial.extra_names.size() != trial.extra_columns.size()) {
    FailWrite(csv_path, std::to_string(trial.extra_names.size()) + " extra column names but " +
                            std::to_string(trial.extra_columns.size()) + " extra columns");
  }
  std::vector<std::pair<std::string, const std::vector<double>*>> columns;
  std::unordered_set<std::string_view> seen;
  for (const auto& [name, col] : required) {
    columns.emplace_back(name, col);
    seen.insert(name);
  }
  for (std::size_t i = 0; i < trial.extra_names.size(); ++i) {
    const std::string& name = trial.extra_names[i];
    if (name.empty() || Trim(name) != name || name.find_first_of(",\r\n") != std::string::npos ||
        name.starts_with(kUtf8Bom)) {
      FailWrite(csv_path,
                "extra column name " + Quote(name) +
                    " must be non-empty, without commas, line breaks or surrounding whitespace");
    }
    if (!seen.insert(name).second) FailWrite(csv_path, "duplicate column name " + Quote(name));
    columns.emplace_back(name, &trial.extra_columns[i]);
  }
  if (n < kMinSamples) {
    FailWrite(csv_path, "has " + std::to_string(n) + " sample(s); a trial needs at least " +
                            std::to_string(kMinSamples));
  }
  for (const auto& [name, col] : columns) {
    if (col->size() != n) {
      FailWrite(csv_path, "column '" + name + "' has " + std::to_string(col->size()) +
                              " samples but 't' has " + std::to_string(n));
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite((*col)[i])) {
        FailWrite(csv_path, "column '" + name + "' sample " + std::to_string(i) + " is not finite");
      }
    }
  }
  for (std::size_t i = 1; i < n; ++i) {
    if (!(trial.t_s[i] > trial.t_s[i - 1])) {
      FailWrite(csv_path, "column 't' is not strictly increasing at sample " + std::to_string(i) +
                              " (t = " + FormatNumber(trial.t_s[i]) + " after " +
                              FormatNumber(trial.t_s[i - 1]) + ")");
    }
  }
  try {
    trial.config.Validate(json_path.string());
  } catch (const std::invalid_argument& e) {
    throw TrialFormatError(e.what());
  }
}

// Writes `text` to `path` via a temporary file and a rename, so readers never see half a file.
void WriteFileAtomically(const fs::path& path, const std::string& text) {
  fs::path tmp = path;
  tmp += ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) FailWrite(path, "cannot open " + tmp.string() + " for writing");
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    out.flush();
    if (!out) {
      std::error_code ignored;
      fs::remove(tmp, ignored);
      FailWrite(path, "write error");
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    FailWrite(path, "cannot rename " + tmp.string() + ": " + ec.message());
  }
}

}  // namespace

Trial ReadTrial(const fs::path& csv_path) {
  const fs::path json_path = SiblingJson(csv_path);
  RequireRegularFile(csv_path, "trial CSV");
  RequireRegularFile(json_path, "sibling JSON of " + csv_path.filename().string());

  Trial trial;
  trial.name = csv_path.stem().string();
  CsvTable csv = ReadCsv(csv_path);
  for (std::size_t c = 0; c < csv.names.size(); ++c) {
    const std::string& name = csv.names[c];
    std::vector<double>& values = csv.values[c];
    if (name == "t") {
      trial.t_s = std::move(values);
    } else if (name == "base_cmd") {
      trial.base_cmd_mm = std::move(values);
    } else if (name == "base") {
      trial.base_mm = std::move(values);
    } else if (name == "tip") {
      trial.tip_mm = std::move(values);
    } else if (name == "force") {
      trial.force_n = std::move(values);
    } else {
      trial.extra_names.push_back(name);
      trial.extra_columns.push_back(std::move(values));
    }
  }
  ReadJson(json_path, trial);
  return trial;
}

std::vector<Trial> ReadDataset(const fs::path& dir) {
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (ec || !fs::exists(st)) FailFile<TrialFormatError>(dir, "dataset folder not found");
  if (!fs::is_directory(st)) FailFile<TrialFormatError>(dir, "dataset path is not a directory");

  std::vector<fs::path> csvs;
  fs::directory_iterator it(dir, ec);
  if (ec) FailFile<TrialFormatError>(dir, "cannot list dataset folder: " + ec.message());
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) FailFile<TrialFormatError>(dir, "cannot list dataset folder: " + ec.message());
    const fs::path& p = it->path();
    std::error_code type_ec;
    if (p.extension() == ".csv" && it->is_regular_file(type_ec)) csvs.push_back(p);
  }
  if (ec) FailFile<TrialFormatError>(dir, "cannot list dataset folder: " + ec.message());
  if (csvs.empty())
    FailFile<TrialFormatError>(dir, "dataset folder holds no trials (no *.csv files)");
  std::sort(csvs.begin(), csvs.end(),
            [](const fs::path& a, const fs::path& b) { return a.filename() < b.filename(); });

  for (const fs::path& csv : csvs) {
    std::error_code json_ec;
    if (!fs::is_regular_file(SiblingJson(csv), json_ec)) {
      FailFile<TrialFormatError>(
          csv,
          "has no sibling JSON " + SiblingJson(csv).filename().string() + " in the dataset folder");
    }
  }
  std::vector<Trial> trials;
  for (const fs::path& csv : csvs) trials.push_back(ReadTrial(csv));
  return trials;
}

void WriteTrial(const fs::path& dir, const Trial& trial) {
  const std::string& name = trial.name;
  if (name.empty() || name == "." || name == ".." ||
      name.find_first_of(std::string_view("/\\\0", 3)) != std::string::npos) {
    throw TrialFormatError((dir / "").string() + ": cannot write trial: invalid trial name " +
                           Quote(name) + " (must be a plain file stem)");
  }
  const fs::path csv_path = dir / (name + ".csv");
  const fs::path json_path = dir / (name + ".json");
  ValidateForWrite(csv_path, json_path, trial);

  Json meta = Json::object();
  if (!Trim(trial.meta_json).empty()) {
    try {
      meta = Json::parse(trial.meta_json);
    } catch (const Json::exception& e) {
      FailWrite(json_path, std::string("meta_json is not valid JSON: ") + e.what());
    }
    if (!meta.is_object()) {
      FailWrite(json_path, "meta_json must be a JSON object, got " + std::string(meta.type_name()));
    }
  }

  Json j = Json::object();
  j["sheath_id_mm"] = trial.config.sheath_id_mm;
  j["guidewire_od_mm"] = trial.config.guidewire_od_mm;
  j["bends"] = Json::array();
  for (const Bend& b : trial.config.bends) {
    Json jb = Json::object();
    jb["angle_deg"] = b.angle_deg;
    jb["radius_mm"] = b.radius_mm;
    j["bends"].push_back(std::move(jb));
  }
  j["tip_load_n"] = trial.config.tip_load_n;
  if (!meta.empty()) j["meta"] = std::move(meta);

  std::string csv = "t,base_cmd,base,tip,force";
  for (const std::string& extra : trial.extra_names) csv += "," + extra;
  csv += '\n';
  for (std::size_t i = 0; i < trial.size(); ++i) {
    AppendNumber(csv, trial.t_s[i]);
    for (const std::vector<double>* col :
         {&trial.base_cmd_mm, &trial.base_mm, &trial.tip_mm, &trial.force_n}) {
      csv += ',';
      AppendNumber(csv, (*col)[i]);
    }
    for (const std::vector<double>& col : trial.extra_columns) {
      csv += ',';
      AppendNumber(csv, col[i]);
    }
    csv += '\n';
  }

  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) FailWrite(dir, "cannot create directory: " + ec.message());
  // JSON first: a crash between the two leaves an orphan JSON, which dataset readers ignore,
  // rather than a CSV without its sibling, which they reject.
  WriteFileAtomically(json_path, j.dump(2) + "\n");
  WriteFileAtomically(csv_path, csv);
}

CatheterConfig ReadCatheterConfig(const std::filesystem::path& json_path) {
  RequireRegularFile(json_path, "catheter configuration");
  const Json j = ParseJsonText(json_path, ReadWholeFile(json_path));
  if (j.is_object()) {
    for (const auto& [k, v] : j.items()) {
      if (!IsGeometryKey(k)) {
        FailFile<TrialFormatError>(json_path,
                                   "key '" + k +
                                       "' is unknown (a catheter configuration has sheath_id_mm, "
                                       "guidewire_od_mm, bends and tip_load_n)");
      }
    }
  }
  return ParseGeometry(json_path, j);
}

}  // namespace echoservo::formats
