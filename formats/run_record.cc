#include "formats/run_record.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <system_error>

#include "formats/csv_table.h"

namespace echoservo::formats {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;  // keeps the metadata's key order
using csv::FormatNumber;
using csv::Quote;

constexpr const char* kFormat = "echoservo-run";
constexpr int kVersion = 1;
constexpr double kMaxHeartRateHz = 10.0;

std::string Line(const fs::path& file, const CsvTable& t, std::size_t row) {
  return file.string() + ": line " + std::to_string(t.lines[row]);
}

const std::vector<std::string> kTargetColumns = {
    "acquired_s", "arrived_s", "published_s", "found",  "target_x_mm", "target_y_mm", "target_z_mm",
    "tip_x_mm",   "tip_y_mm",  "tip_z_mm",    "axis_x", "axis_y",      "axis_z",      "confidence"};
const std::vector<std::string> kServoColumns = {
    "t_s", "mode", "setpoint_mm", "base_mm", "tip_estimate_mm", "faults"};
const std::vector<std::string> kLatencyColumns = {"arrived_s", "applied_s"};
const std::vector<std::string> kTruthColumns = {
    "t_s", "target_x_mm", "target_y_mm", "target_z_mm", "tip_x_mm", "tip_y_mm", "tip_z_mm"};

std::string Joined(const std::vector<std::string>& names) {
  std::string s;
  for (const std::string& n : names) s += (s.empty() ? "" : ",") + n;
  return s;
}

CsvTable ReadTable(const fs::path& path, const std::vector<std::string>& columns,
                   std::size_t min_rows, const std::string& what,
                   std::vector<std::string> text_columns = {}) {
  CsvTableSpec spec;
  spec.required = columns;
  spec.required_hint = "(header: " + Joined(columns) + ")";
  spec.time_column = columns.front();
  spec.text_columns = std::move(text_columns);
  spec.min_rows = min_rows;
  spec.what = what;
  return ReadCsvTable(path, spec);
}

// The column `name` of `t` (present: ReadCsvTable checked the required columns).
const std::vector<double>& Col(const CsvTable& t, const std::string& name) {
  return t.values[t.Index(name)];
}

Eigen::Vector3d Vec(const CsvTable& t, const std::string& prefix, const std::string& suffix,
                    std::size_t row) {
  return {Col(t, prefix + "x" + suffix)[row], Col(t, prefix + "y" + suffix)[row],
          Col(t, prefix + "z" + suffix)[row]};
}

// `later` ≥ `earlier` on every row, else an error naming the line.
void RequireOrder(const fs::path& path, const CsvTable& t, const std::string& earlier,
                  const std::string& later) {
  const auto& a = Col(t, earlier);
  const auto& b = Col(t, later);
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (b[i] < a[i]) {
      throw std::invalid_argument(Line(path, t, i) + ": column '" + later +
                                  "': " + FormatNumber(b[i]) + " s is before " + earlier + " = " +
                                  FormatNumber(a[i]) + " s");
    }
  }
}

// The JSON document in `path`; errors name the file (`missing` says why it must exist).
Json ParseJsonFile(const fs::path& path, const std::string& missing) {
  std::ifstream in(path, std::ios::binary);
  if (!in) FailFile(path, "cannot open file for reading" + missing);
  try {
    return Json::parse(in);
  } catch (const Json::exception& e) {
    FailFile(path, std::string("not valid JSON: ") + e.what());
  }
}

// The typed metadata keys (formats/run_metadata.h), besides format, version, heart_rate_hz,
// standoff_mm and notes.
const char* const kMetaKeys[] = {"source",     "time_base", "em_to_image",        "seed",
                                 "duration_s", "replay_of", "pipeline_to_unix_s", "settings"};

bool IsReservedKey(const std::string& key) {
  for (const char* k : {"format", "version", "heart_rate_hz", "standoff_mm", "notes"})
    if (key == k) return true;
  for (const char* k : kMetaKeys)
    if (key == k) return true;
  return false;
}

std::string KeyWhere(const fs::path& path, const char* key) {
  return path.string() + ": key '" + key + "'";
}

std::string MetaString(const fs::path& path, const Json& j, const char* key) {
  if (!j.contains(key) || j[key].is_null()) return "";
  if (!j[key].is_string()) FailFile(path, std::string("key '") + key + "' must be a string");
  return j[key].get<std::string>();
}

std::optional<double> MetaNumber(const fs::path& path, const Json& j, const char* key) {
  if (!j.contains(key) || j[key].is_null()) return std::nullopt;
  if (!j[key].is_number() || !std::isfinite(j[key].get<double>()))
    FailFile(path, std::string("key '") + key + "': " + j[key].dump() + " is not a finite number");
  return j[key].get<double>();
}

void ReadRunMetadata(const fs::path& path, const Json& j, RunInfo& info) {
  RunMetadata& m = info.meta;
  m.source = MetaString(path, j, "source");
  const std::string base = MetaString(path, j, "time_base");
  if (base == "pipeline") {
    m.time_base = RunTimeBase::kPipeline;
  } else if (base == "unix") {
    m.time_base = RunTimeBase::kUnix;
  } else if (base == "recording") {
    m.time_base = RunTimeBase::kRecording;
  } else if (!base.empty()) {
    FailFile(path, "key 'time_base': '" + base + "' is not one of pipeline, unix, recording");
  }
  if (j.contains("em_to_image") && !j["em_to_image"].is_null()) {
    const Json& t = j["em_to_image"];
    if (t.is_string()) {
      m.em_to_image = ParseRigidTransform(t.get<std::string>(), KeyWhere(path, "em_to_image"));
    } else if (t.is_array()) {
      std::string text;
      for (const Json& x : t) {
        if (!x.is_number()) FailFile(path, "key 'em_to_image': " + x.dump() + " is not a number");
        text += FormatNumber(x.get<double>()) + " ";
      }
      m.em_to_image = ParseRigidTransform(text, KeyWhere(path, "em_to_image"));
    } else {
      FailFile(path, "key 'em_to_image' must be a string (or an array) of 12 or 16 numbers");
    }
  }
  if (j.contains("seed") && !j["seed"].is_null()) {
    if (!j["seed"].is_number_unsigned())
      FailFile(path, "key 'seed': " + j["seed"].dump() + " is not a non-negative integer");
    m.seed = j["seed"].get<std::uint64_t>();
  }
  m.duration_s = MetaNumber(path, j, "duration_s");
  if (m.duration_s && !(*m.duration_s > 0.0))
    FailFile(path, "key 'duration_s': " + FormatNumber(*m.duration_s) + " must be > 0 s");
  m.replay_of = MetaString(path, j, "replay_of");
  m.pipeline_to_unix_s = MetaNumber(path, j, "pipeline_to_unix_s");
  if (j.contains("settings") && !j["settings"].is_null()) {
    if (!j["settings"].is_object())
      FailFile(path, "key 'settings' must be an object {\"name\": number}");
    for (const auto& [name, value] : j["settings"].items()) {
      if (!value.is_number() || !std::isfinite(value.get<double>()))
        FailFile(path,
                 "key 'settings': '" + name + "': " + value.dump() + " is not a finite number");
      m.settings.emplace_back(name, value.get<double>());
    }
  }
  for (const char* key : {"source", "time_base"})
    if (!j.contains(key))
      info.warnings.push_back(path.string() + ": no '" + key +
                              "' (a RUN written before typed metadata): read as before");
  Json extra = Json::object();
  for (const auto& [key, value] : j.items())
    if (!IsReservedKey(key)) extra[key] = value;
  info.extra_json = extra.dump();
}

void WriteRunMetadata(const RunInfo& info, Json& j) {
  const RunMetadata& m = info.meta;
  if (!m.source.empty()) j["source"] = m.source;
  if (m.time_base != RunTimeBase::kUnstated) j["time_base"] = std::string(ToString(m.time_base));
  if (m.em_to_image) j["em_to_image"] = FormatRigidTransform(*m.em_to_image);
  if (m.seed) j["seed"] = *m.seed;
  if (m.duration_s) {
    if (!(*m.duration_s > 0.0) || !std::isfinite(*m.duration_s))
      throw std::invalid_argument("RunMetadata::duration_s must be finite and > 0 s");
    j["duration_s"] = *m.duration_s;
  }
  if (!m.replay_of.empty()) j["replay_of"] = m.replay_of;
  if (m.pipeline_to_unix_s) {
    if (!std::isfinite(*m.pipeline_to_unix_s))
      throw std::invalid_argument("RunMetadata::pipeline_to_unix_s must be finite");
    j["pipeline_to_unix_s"] = *m.pipeline_to_unix_s;
  }
  if (!m.settings.empty()) {
    Json s = Json::object();
    for (const auto& [name, value] : m.settings) {
      if (!std::isfinite(value))
        throw std::invalid_argument("RunMetadata::settings: '" + name + "' is not finite");
      s[name] = value;
    }
    j["settings"] = s;
  }
}

RunInfo ReadRunJson(const fs::path& path) {
  const Json j = ParseJsonFile(path, " (every RUN directory has a run.json)");
  if (!j.is_object()) FailFile(path, "must be a JSON object");
  if (!j.contains("format") || j["format"] != kFormat) {
    FailFile(path, std::string("key 'format' must be \"") + kFormat + "\"");
  }
  if (!j.contains("version") || !j["version"].is_number_integer()) {
    FailFile(path, "key 'version' must be an integer (1)");
  }
  if (j["version"].get<long long>() != kVersion) {
    FailFile(path, "key 'version': " + j["version"].dump() +
                       " is not a version this reader knows (" + std::to_string(kVersion) + ")");
  }
  RunInfo info;
  if (j.contains("heart_rate_hz") && !j["heart_rate_hz"].is_null()) {
    const Json& hr = j["heart_rate_hz"];
    if (!hr.is_number() || !(hr.get<double>() > 0.0) || hr.get<double>() > kMaxHeartRateHz) {
      FailFile(path, "key 'heart_rate_hz': " + hr.dump() + " is not a number in (0, 10] Hz");
    }
    info.heart_rate_hz = hr.get<double>();
  }
  if (j.contains("standoff_mm") && !j["standoff_mm"].is_null()) {
    const Json& so = j["standoff_mm"];
    if (!so.is_number() || !(so.get<double>() >= 0.0) || so.get<double>() > 50.0) {
      FailFile(path, "key 'standoff_mm': " + so.dump() + " is not a number in [0, 50] mm");
    }
    info.standoff_mm = so.get<double>();
  }
  if (j.contains("notes")) {
    if (!j["notes"].is_string()) FailFile(path, "key 'notes' must be a string");
    info.notes = j["notes"].get<std::string>();
  }
  ReadRunMetadata(path, j, info);
  return info;
}

bool Exists(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

constexpr const char* kTrackerCountKeys[] = {"acquired", "missed",    "shed",
                                             "skipped",  "processed", "not_found"};
std::uint64_t* TrackerCountField(TrackerVolumeCounts& c, std::size_t i) {
  std::uint64_t* fields[] = {&c.acquired, &c.missed,    &c.shed,
                             &c.skipped,  &c.processed, &c.not_found};
  return fields[i];
}

}  // namespace

std::string TrackerCountsJson(const TrackerVolumeCounts& counts) {
  TrackerVolumeCounts c = counts;
  Json j = Json::object();
  for (std::size_t i = 0; i < std::size(kTrackerCountKeys); ++i)
    j[kTrackerCountKeys[i]] = *TrackerCountField(c, i);
  return j.dump(2);
}

namespace {

// tracker.json (optional): every count present, a non-negative integer, and consistent.
TrackerVolumeCounts ReadTrackerCountsJson(const fs::path& path) {
  constexpr std::uintmax_t kMaxBytes = 1 << 16;
  std::error_code ec;
  if (fs::file_size(path, ec) > kMaxBytes) FailFile(path, "larger than 64 KiB: not a tracker.json");
  const Json j = ParseJsonFile(path, "");
  if (!j.is_object()) FailFile(path, "must be a JSON object");
  TrackerVolumeCounts c;
  for (std::size_t i = 0; i < std::size(kTrackerCountKeys); ++i) {
    const char* key = kTrackerCountKeys[i];
    if (!j.contains(key) || !j[key].is_number_unsigned())
      FailFile(path, std::string("key '") + key + "' must be a count (an integer ≥ 0)");
    *TrackerCountField(c, i) = j[key].get<std::uint64_t>();
  }
  if (c.processed > c.acquired || c.shed > c.acquired)
    FailFile(path, "keys 'processed' and 'shed' cannot exceed 'acquired'");
  if (c.not_found > c.processed) FailFile(path, "key 'not_found' exceeds 'processed'");
  return c;
}

// timing.json (optional): the keys the report shows, each checked for its type and range.
ServoTimingRecord ReadTimingJson(const fs::path& path) {
  constexpr std::uintmax_t kMaxBytes = 1 << 20;
  std::error_code ec;
  if (fs::file_size(path, ec) > kMaxBytes) FailFile(path, "larger than 1 MiB: not a timing.json");
  const Json j = ParseJsonFile(path, "");
  auto object = [&](const Json& parent, const char* key) -> const Json& {
    if (!parent.is_object() || !parent.contains(key) || !parent[key].is_object())
      FailFile(path, std::string("key '") + key + "' must be an object");
    return parent[key];
  };
  auto number = [&](const Json& o, const char* key, const char* where) {
    if (!o.contains(key) || !o[key].is_number() || !std::isfinite(o[key].get<double>()) ||
        o[key].get<double>() < 0.0)
      FailFile(path, std::string("key '") + where + "." + key + "' must be a number ≥ 0");
    return o[key].get<double>();
  };
  auto count = [&](const Json& o, const char* key, const char* where) {
    if (!o.contains(key) || !o[key].is_number_unsigned())
      FailFile(path, std::string("key '") + where + "." + key + "' must be a count");
    return o[key].get<std::uint64_t>();
  };
  ServoTimingRecord t;
  const Json& rt = object(j, "realtime");
  if (!rt.contains("summary") || !rt["summary"].is_string())
    FailFile(path, "key 'realtime.summary' must be a string");
  t.realtime_summary = rt["summary"].get<std::string>();
  if (!rt.contains("fifo") || !rt["fifo"].is_boolean())
    FailFile(path, "key 'realtime.fifo' must be true or false");
  t.fifo = rt["fifo"].get<bool>();
  if (rt.contains("refusals")) {
    if (!rt["refusals"].is_array()) FailFile(path, "key 'realtime.refusals' must be an array");
    for (const Json& r : rt["refusals"]) {
      if (!r.is_string()) FailFile(path, "key 'realtime.refusals' must hold strings");
      t.refusals.push_back(r.get<std::string>());
    }
  }
  const Json& tm = object(j, "timing");
  t.period_s = number(tm, "period_s", "timing");
  t.cycles = count(tm, "cycles", "timing");
  t.overruns = count(tm, "overruns", "timing");
  if (t.overruns > t.cycles) FailFile(path, "key 'timing.overruns' exceeds 'timing.cycles'");
  t.max_consecutive_overruns = count(tm, "max_consecutive_overruns", "timing");
  t.overrun_fraction = number(tm, "overrun_fraction", "timing");
  const Json& wake = object(tm, "wakeup_latency_us");
  t.wakeup_p50_us = number(wake, "p50", "timing.wakeup_latency_us");
  t.wakeup_p99_us = number(wake, "p99", "timing.wakeup_latency_us");
  t.wakeup_p999_us = number(wake, "p999", "timing.wakeup_latency_us");
  t.wakeup_max_us = number(wake, "max", "timing.wakeup_latency_us");
  const Json& cycle = object(tm, "cycle_duration_us");
  t.cycle_p50_us = number(cycle, "p50", "timing.cycle_duration_us");
  t.cycle_p99_us = number(cycle, "p99", "timing.cycle_duration_us");
  t.cycle_p999_us = number(cycle, "p999", "timing.cycle_duration_us");
  t.cycle_max_us = number(cycle, "max", "timing.cycle_duration_us");
  const Json& dl = object(j, "deadline");
  t.deadline_holds = count(dl, "holds", "deadline");
  t.deadline_retracts = count(dl, "retracts", "deadline");
  return t;
}

void AppendValue(std::string& row, double v, const fs::path& file, const char* column) {
  if (!std::isfinite(v)) {
    throw std::invalid_argument(file.string() + ": column '" + column +
                                "': the value is not finite");
  }
  if (!row.empty()) row += ',';
  csv::AppendNumber(row, v);
}

void AppendVector(std::string& row, const Eigen::Vector3d& v, const fs::path& file,
                  const char* column) {
  for (int k = 0; k < 3; ++k) AppendValue(row, v[k], file, column);
}

}  // namespace

RunRecord ReadRunRecord(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) FailFile(dir, "not a RUN directory (no such folder)");
  RunRecord run;
  run.dir = dir;
  run.info = ReadRunJson(dir / "run.json");

  const fs::path targets_path = dir / "targets.csv";
  if (!Exists(targets_path)) FailFile(targets_path, "not found (every RUN directory has one)");
  const CsvTable t = ReadTable(targets_path, kTargetColumns, 2, "a RUN's targets.csv");
  RequireOrder(targets_path, t, "acquired_s", "arrived_s");
  RequireOrder(targets_path, t, "arrived_s", "published_s");
  for (std::size_t i = 0; i < t.lines.size(); ++i) {
    TargetRecord r;
    r.acquired_s = Col(t, "acquired_s")[i];
    r.arrived_s = Col(t, "arrived_s")[i];
    r.published_s = Col(t, "published_s")[i];
    const double found = Col(t, "found")[i];
    if (found != 0.0 && found != 1.0) {
      throw std::invalid_argument(Line(targets_path, t, i) +
                                  ": column 'found': " + FormatNumber(found) + " is not 0 or 1");
    }
    r.found = found == 1.0;
    r.target_mm = Vec(t, "target_", "_mm", i);
    r.tip_mm = Vec(t, "tip_", "_mm", i);
    r.axis = Vec(t, "axis_", "", i);
    r.confidence = Col(t, "confidence")[i];
    run.targets.push_back(r);
  }

  const fs::path servo_path = dir / "servo.csv";
  run.has_servo = Exists(servo_path);
  if (run.has_servo) {
    const CsvTable s = ReadTable(servo_path, kServoColumns, 1, "a RUN's servo.csv", {"mode"});
    const auto& mode = s.text[s.Index("mode")];
    for (std::size_t i = 0; i < s.lines.size(); ++i) {
      run.servo.push_back({Col(s, "t_s")[i], mode[i], Col(s, "setpoint_mm")[i],
                           Col(s, "base_mm")[i], Col(s, "tip_estimate_mm")[i],
                           Col(s, "faults")[i]});
    }
  }

  const fs::path latency_path = dir / "latency.csv";
  run.has_latency = Exists(latency_path);
  if (run.has_latency) {
    const CsvTable l = ReadTable(latency_path, kLatencyColumns, 1, "a RUN's latency.csv");
    RequireOrder(latency_path, l, "arrived_s", "applied_s");
    for (std::size_t i = 0; i < l.lines.size(); ++i) {
      run.latency.push_back({Col(l, "arrived_s")[i], Col(l, "applied_s")[i]});
    }
  }

  const fs::path truth_path = dir / "truth.csv";
  run.has_truth = Exists(truth_path);
  if (run.has_truth) {
    const CsvTable g = ReadTable(truth_path, kTruthColumns, 2, "a RUN's truth.csv");
    for (std::size_t i = 0; i < g.lines.size(); ++i) {
      run.truth.push_back(
          {Col(g, "t_s")[i], Vec(g, "target_", "_mm", i), Vec(g, "tip_", "_mm", i)});
    }
  }
  run.has_em = Exists(run.EmPath());
  const fs::path timing_path = dir / "timing.json";
  run.has_timing = Exists(timing_path);
  if (run.has_timing) run.timing = ReadTimingJson(timing_path);
  const fs::path tracker_path = dir / "tracker.json";
  run.has_tracker_counts = Exists(tracker_path);
  if (run.has_tracker_counts) run.tracker = ReadTrackerCountsJson(tracker_path);
  return run;
}

RunWriter::RunWriter(const fs::path& dir, const RunInfo& info) : dir_(dir) {
  fs::create_directories(dir);
  const fs::path json_path = dir / "run.json";
  if (Exists(json_path)) FailFile(json_path, "already exists: a RUN directory is written once");
  Json extra;
  try {
    extra = Json::parse(info.extra_json);
  } catch (const Json::exception& e) {
    throw std::invalid_argument(std::string("RunInfo::extra_json: not valid JSON: ") + e.what());
  }
  if (!extra.is_object()) throw std::invalid_argument("RunInfo::extra_json: not a JSON object");
  Json j = {{"format", kFormat}, {"version", kVersion}};
  if (info.heart_rate_hz) {
    if (!(*info.heart_rate_hz > 0.0) || *info.heart_rate_hz > kMaxHeartRateHz) {
      throw std::invalid_argument("RunInfo::heart_rate_hz must be in (0, 10] Hz");
    }
    j["heart_rate_hz"] = *info.heart_rate_hz;
  }
  if (info.standoff_mm) {
    if (!(*info.standoff_mm >= 0.0 && *info.standoff_mm <= 50.0))
      throw std::invalid_argument("RunInfo::standoff_mm must be in [0, 50] mm");
    j["standoff_mm"] = *info.standoff_mm;
  }
  if (!info.notes.empty()) j["notes"] = info.notes;
  WriteRunMetadata(info, j);
  for (const auto& [key, value] : extra.items()) {
    if (IsReservedKey(key))
      throw std::invalid_argument("RunInfo::extra_json: key '" + key +
                                  "' is typed (RunInfo, RunMetadata): set it there");
    j[key] = value;
  }
  std::ofstream out(json_path, std::ios::binary | std::ios::trunc);
  out << j.dump(2) << "\n";
  if (!out) throw std::runtime_error(json_path.string() + ": write error");

  const std::pair<File*, std::pair<const char*, std::string>> files[] = {
      {&targets_, {"targets.csv", Joined(kTargetColumns)}},
      {&servo_, {"servo.csv", Joined(kServoColumns)}},
      {&latency_, {"latency.csv", Joined(kLatencyColumns)}},
      {&em_, {"em.csv", SimEmLogHeader()}},
      {&truth_, {"truth.csv", Joined(kTruthColumns)}}};
  for (const auto& [file, spec] : files) {
    file->path = dir / spec.first;
    file->header = spec.second;
  }
}

RunWriter::~RunWriter() = default;

void RunWriter::Append(File& f, double t_s, const std::string& row) {
  std::lock_guard lock(f.mutex);
  if (f.any && !(t_s > f.last_t_s)) {
    throw std::invalid_argument(f.path.string() + ": time " + FormatNumber(t_s) +
                                " s is not after the previous row's " + FormatNumber(f.last_t_s) +
                                " s");
  }
  std::string text;
  if (!f.file.is_open()) {
    f.file = AppendOnlyFile(f.path);
    text = f.header + "\n";  // the header goes out with the first row
  }
  text += row;
  text += '\n';
  f.file.Append(text);
  f.last_t_s = t_s;
  f.any = true;
}

void RunWriter::AddTarget(const TargetRecord& r) {
  const fs::path& p = targets_.path;
  if (r.arrived_s < r.acquired_s || r.published_s < r.arrived_s) {
    throw std::invalid_argument(p.string() + ": acquired_s ≤ arrived_s ≤ published_s is violated");
  }
  std::string row;
  AppendValue(row, r.acquired_s, p, "acquired_s");
  AppendValue(row, r.arrived_s, p, "arrived_s");
  AppendValue(row, r.published_s, p, "published_s");
  row += r.found ? ",1" : ",0";
  AppendVector(row, r.found ? r.target_mm : Eigen::Vector3d::Zero(), p, "target_mm");
  AppendVector(row, r.found ? r.tip_mm : Eigen::Vector3d::Zero(), p, "tip_mm");
  AppendVector(row, r.found ? r.axis : Eigen::Vector3d::Zero(), p, "axis");
  AppendValue(row, r.found ? r.confidence : 0.0, p, "confidence");
  Append(targets_, r.acquired_s, row);
}

void RunWriter::AddServo(const ServoRecord& r) {
  const fs::path& p = servo_.path;
  if (r.mode.find_first_of(",\r\n") != std::string::npos || r.mode.empty()) {
    throw std::invalid_argument(p.string() + ": column 'mode': " + Quote(r.mode) +
                                " must be a non-empty label without a comma or line break");
  }
  std::string row;
  AppendValue(row, r.t_s, p, "t_s");
  row += "," + r.mode;
  AppendValue(row, r.setpoint_mm, p, "setpoint_mm");
  AppendValue(row, r.base_mm, p, "base_mm");
  AppendValue(row, r.tip_estimate_mm, p, "tip_estimate_mm");
  AppendValue(row, r.faults, p, "faults");
  Append(servo_, r.t_s, row);
}

void RunWriter::AddLatency(const LatencyRecord& r) {
  const fs::path& p = latency_.path;
  if (r.applied_s < r.arrived_s) {
    throw std::invalid_argument(p.string() + ": applied_s is before arrived_s");
  }
  std::string row;
  AppendValue(row, r.arrived_s, p, "arrived_s");
  AppendValue(row, r.applied_s, p, "applied_s");
  Append(latency_, r.arrived_s, row);
}

void RunWriter::AddEm(const EmSample& s) {
  std::string check;
  AppendValue(check, s.t_s, em_.path, "t_s");
  if (s.valid) AppendVector(check, s.position_mm, em_.path, "position_mm");
  Append(em_, s.t_s, SimEmLogRow(s));
}

void RunWriter::AddTruth(const TruthRecord& r) {
  const fs::path& p = truth_.path;
  std::string row;
  AppendValue(row, r.t_s, p, "t_s");
  AppendVector(row, r.target_mm, p, "target_mm");
  AppendVector(row, r.tip_mm, p, "tip_mm");
  Append(truth_, r.t_s, row);
}

void RunWriter::Flush() {
  for (File* f : {&targets_, &servo_, &latency_, &em_, &truth_}) {
    std::lock_guard lock(f->mutex);
    f->file.SyncData();
  }
}

}  // namespace echoservo::formats
