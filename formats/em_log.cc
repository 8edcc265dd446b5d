#include "formats/em_log.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string_view>

#include "formats/csv_table.h"

namespace echoservo::formats {
namespace {

namespace fs = std::filesystem;
using csv::FormatNumber;
using csv::Quote;
using csv::Trim;

constexpr std::size_t kHeaderSearchLines = 10;   // the Aurora header is within these
constexpr std::size_t kAuroraTimeColumns = 5;    // Sample:, Hour, Minutes, Seconds, ms
constexpr std::size_t kAuroraSensorColumns = 7;  // X, Y, Z, qo, qx, qy, qz
constexpr double kDayS = 86400.0;

std::string Where(const fs::path& file, std::size_t line) {
  return file.string() + ": line " + std::to_string(line);
}

std::string Lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

// Lines of a text file, without line ends or a leading byte-order mark.
std::vector<std::string> ReadLines(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) FailFile(path, "cannot open file for reading");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (lines.empty() && std::string_view(line).starts_with(kUtf8Bom)) {
      line.erase(0, kUtf8Bom.size());
    }
    lines.push_back(std::move(line));
  }
  if (in.bad()) FailFile(path, "read error");
  return lines;
}

std::vector<std::string_view> SplitFields(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t pos = 0;
  while (true) {
    const std::size_t comma = line.find(',', pos);
    fields.push_back(Trim(line.substr(pos, comma == std::string_view::npos ? comma : comma - pos)));
    if (comma == std::string_view::npos) break;
    pos = comma + 1;
  }
  return fields;
}

// One field as a number; throws naming the line and the column.
double ParseField(std::string_view field, const std::string& where, const std::string& column) {
  double v = 0.0;
  switch (csv::ParseNumber(field, v)) {
    case csv::NumberStatus::kOk:
      return v;
    case csv::NumberStatus::kNonFinite:
      throw std::invalid_argument(where + ": column '" + column +
                                  "': NaN or infinity is not allowed: " + Quote(field));
    case csv::NumberStatus::kOutOfRange:
      throw std::invalid_argument(where + ": column '" + column +
                                  "': number out of the range of a double: " + Quote(field));
    default:
      throw std::invalid_argument(where + ": column '" + column +
                                  "': not a number: " + Quote(field));
  }
}

// A whole number in [lo, hi]; throws naming the line and the column.
double ParseWhole(std::string_view field, double lo, double hi, const std::string& where,
                  const std::string& column) {
  const double v = ParseField(field, where, column);
  if (v != std::floor(v) || v < lo || v > hi) {
    throw std::invalid_argument(where + ": column '" + column + "': " + Quote(field) +
                                " is not a whole number in [" + FormatNumber(lo) + ", " +
                                FormatNumber(hi) + "]");
  }
  return v;
}

// The Aurora header: `Sample:,Hour,Minutes,Seconds,ms`, then 7 columns per sensor named
// X<s>,Y<s>,Z<s>,qo<s>,qx<s>,qy<s>,qz<s>. Returns the sensor suffixes.
std::vector<std::string> AuroraSensors(const std::vector<std::string_view>& names,
                                       const std::string& where) {
  static constexpr std::array<const char*, kAuroraTimeColumns> kTime = {"Sample:", "Hour",
                                                                        "Minutes", "Seconds", "ms"};
  static constexpr std::array<const char*, kAuroraSensorColumns> kPrefix = {"X",  "Y",  "Z", "qo",
                                                                            "qx", "qy", "qz"};
  for (std::size_t i = 0; i < kTime.size(); ++i) {
    if (i >= names.size() || names[i] != kTime[i]) {
      throw std::invalid_argument(
          where + ": column " + std::to_string(i + 1) + " of the Aurora header must be '" +
          kTime[i] + "' (header: Sample:,Hour,Minutes,Seconds,ms,Xa,Ya,Za,qoa,qxa,qya,qza,…)");
    }
  }
  const std::size_t rest = names.size() - kAuroraTimeColumns;
  if (rest == 0 || rest % kAuroraSensorColumns != 0) {
    throw std::invalid_argument(where + ": the Aurora header has " + std::to_string(rest) +
                                " sensor columns after 'ms'; expected 7 per sensor (X, Y, Z, "
                                "qo, qx, qy, qz with the sensor's letter)");
  }
  std::vector<std::string> sensors;
  for (std::size_t s = 0; s < rest / kAuroraSensorColumns; ++s) {
    const std::size_t first = kAuroraTimeColumns + s * kAuroraSensorColumns;
    // An empty column name has no sensor letter (and no substr(1)): reported below.
    const std::string suffix(names[first].empty() ? std::string_view{} : names[first].substr(1));
    for (std::size_t k = 0; k < kPrefix.size(); ++k) {
      const std::string expected = kPrefix[k] + suffix;
      if (suffix.empty() || names[first + k] != expected) {
        throw std::invalid_argument(where + ": column " + std::to_string(first + k + 1) +
                                    " of the Aurora header is " + Quote(names[first + k]) +
                                    "; expected '" + (suffix.empty() ? "Xa" : expected) + "'");
      }
    }
    sensors.push_back(suffix);
  }
  return sensors;
}

// Index of the sensor named by `choice` (1-based index or letter) among `sensors`.
std::optional<std::size_t> PickSensor(const std::string& choice,
                                      const std::vector<std::string>& sensors) {
  if (choice.empty()) return std::nullopt;
  if (std::all_of(choice.begin(), choice.end(), [](unsigned char c) { return std::isdigit(c); })) {
    const std::size_t index = choice.size() > 3 ? 0 : std::stoul(choice);
    if (index >= 1 && index <= sensors.size()) return index - 1;
  }
  for (std::size_t i = 0; i < sensors.size(); ++i) {
    if (Lower(sensors[i]) == Lower(choice)) return i;
  }
  return sensors.size();  // not found
}

std::string SensorList(const std::vector<std::string>& sensors,
                       const std::vector<std::size_t>& valid) {
  std::string s;
  for (std::size_t i = 0; i < sensors.size(); ++i) {
    s += (i ? ", " : "") + std::to_string(i + 1) + " (" + sensors[i] + ", " +
         std::to_string(valid[i]) + " valid)";
  }
  return s;
}

}  // namespace

EmLogFormat ParseEmLogFormat(const std::string& text) {
  if (text == "auto") return EmLogFormat::kAuto;
  if (text == "plus") return EmLogFormat::kPlus;
  if (text == "aurora") return EmLogFormat::kAurora;
  if (text == "sim") return EmLogFormat::kSim;
  throw std::invalid_argument("EM log format " + Quote(text) +
                              " is not one of auto, plus, aurora, sim");
}

const char* EmLogFormatName(EmLogFormat format) {
  switch (format) {
    case EmLogFormat::kAuto:
      return "auto";
    case EmLogFormat::kPlus:
      return "plus";
    case EmLogFormat::kAurora:
      return "aurora";
    case EmLogFormat::kSim:
      return "sim";
  }
  return "?";
}

LengthUnit ParseLengthUnit(const std::string& text) {
  if (text == "mm") return LengthUnit::kMillimetre;
  if (text == "in") return LengthUnit::kInch;
  throw std::invalid_argument("length unit " + Quote(text) + " is not one of mm, in");
}

const char* LengthUnitName(LengthUnit unit) { return unit == LengthUnit::kInch ? "in" : "mm"; }

double MillimetresPerUnit(LengthUnit unit) { return unit == LengthUnit::kInch ? 25.4 : 1.0; }

std::size_t EmLog::valid_samples() const {
  return static_cast<std::size_t>(
      std::count_if(samples.begin(), samples.end(), [](const EmSample& s) { return s.valid; }));
}

std::size_t EmLog::dropouts() const {
  std::size_t n = 0;
  for (const auto& [reason, count] : dropouts_by_reason) n += count;
  return n;
}

double EmLog::MedianPeriodS() const {
  if (samples.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  std::vector<double> dt;
  dt.reserve(samples.size() - 1);
  for (std::size_t i = 1; i < samples.size(); ++i)
    dt.push_back(samples[i].t_s - samples[i - 1].t_s);
  std::nth_element(dt.begin(), dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2), dt.end());
  return dt[dt.size() / 2];
}

EmLogAppender::EmLogAppender(EmLog& log, LengthUnit units)
    : log_(log), scale_(MillimetresPerUnit(units)) {
  log_.file_units = units;
}

void EmLogAppender::CheckTime(double t_s, const std::string& where) {
  if (!std::isfinite(t_s)) throw std::invalid_argument(where + ": the time is not finite");
  if (!log_.samples.empty() && !(t_s > log_.samples.back().t_s)) {
    throw std::invalid_argument(where +
                                ": times must be strictly increasing (t = " + FormatNumber(t_s) +
                                " s is not after t = " + FormatNumber(log_.samples.back().t_s) +
                                " s at " + previous_where_ + ")");
  }
  previous_where_ = where;
}

void EmLogAppender::AddValid(double t_s, const Eigen::Vector3d& position,
                             const std::string& where) {
  CheckTime(t_s, where);
  if (!position.allFinite()) throw std::invalid_argument(where + ": the position is not finite");
  log_.samples.push_back({t_s, scale_ * position, true});
}

void EmLogAppender::AddDropout(double t_s, const std::string& reason, const std::string& where) {
  CheckTime(t_s, where);
  log_.samples.push_back({t_s, Eigen::Vector3d::Zero(), false});
  ++log_.dropouts_by_reason[reason];
}

void EmLogAppender::CountMissing(const std::string& reason, std::size_t count) {
  if (count > 0) log_.dropouts_by_reason[reason] += count;
}

EmLogFormat DetectEmLogFormat(const fs::path& path) {
  const std::string name = Lower(path.filename().string());
  if (name.ends_with(".mha") || name.ends_with(".nrrd")) return EmLogFormat::kPlus;
  std::ifstream in(path, std::ios::binary);
  if (!in) FailFile(path, "cannot open file for reading");
  std::string line;
  for (std::size_t n = 0; n < kHeaderSearchLines && std::getline(in, line); ++n) {
    std::string_view view = line;
    if (n == 0 && view.starts_with(kUtf8Bom)) view.remove_prefix(kUtf8Bom.size());
    view = Trim(view);
    if (view.starts_with("Sample:") || (n == 0 && view.starts_with("Test Date"))) {
      return EmLogFormat::kAurora;
    }
    if (n == 0 && Trim(view.substr(0, view.find(','))) == "t_s") return EmLogFormat::kSim;
  }
  FailFile(path,
           "cannot tell the EM log format: not a PLUS sequence (.mha, .nrrd), no Aurora 'Sample:' "
           "header, no 't_s' column of the simulated tracker; give the format (--em-format "
           "plus|aurora|sim)");
}

LengthUnit ResolveUnits(const fs::path& path, const EmImportOptions& options,
                        std::optional<LengthUnit> file_units) {
  if (options.units && file_units && *options.units != *file_units) {
    FailFile(path, std::string("the file's positions are in ") + LengthUnitName(*file_units) +
                       " but " + LengthUnitName(*options.units) +
                       " were declared (--em-units); declare the file's units");
  }
  if (options.units) return *options.units;
  return file_units.value_or(LengthUnit::kMillimetre);
}

EmLog ReadAuroraEmLog(const fs::path& path, const EmImportOptions& options) {
  const std::vector<std::string> lines = ReadLines(path);
  std::size_t header = lines.size();
  for (std::size_t i = 0; i < std::min(lines.size(), kHeaderSearchLines); ++i) {
    if (Trim(lines[i]).starts_with("Sample:")) {
      header = i;
      break;
    }
  }
  if (header == lines.size()) {
    FailFile(path, "no Aurora header line (starting with 'Sample:') in the first " +
                       std::to_string(kHeaderSearchLines) + " lines");
  }
  std::vector<std::string_view> names = SplitFields(lines[header]);
  while (!names.empty() && names.back().empty()) names.pop_back();
  EmLog log;
  log.source = path;
  log.format = EmLogFormat::kAurora;
  log.sensors = AuroraSensors(names, Where(path, header + 1));
  const std::size_t columns = names.size();

  // All rows first: the sensor may be chosen by which one has data.
  std::size_t last = lines.size();
  while (last > header + 1 && Trim(lines[last - 1]).empty()) --last;
  struct Row {
    std::size_t line;
    double t_s;
    std::vector<double> values;  // the sensor columns
  };
  std::vector<Row> rows;
  double day_s = 0.0, previous_s = -1.0, previous_sample = -1.0;
  std::size_t missing_samples = 0;
  for (std::size_t i = header + 1; i < last; ++i) {
    const std::string where = Where(path, i + 1);
    if (Trim(lines[i]).empty()) {
      throw std::invalid_argument(where + ": empty line inside the data");
    }
    std::vector<std::string_view> fields = SplitFields(lines[i]);
    if (fields.size() > 1 && fields.back().empty()) fields.pop_back();  // a trailing comma
    if (fields.size() != columns) {
      if (i + 1 == last && fields.size() < columns) {
        log.notes.push_back("line " + std::to_string(i + 1) + ": the last row has " +
                            std::to_string(fields.size()) + " of " + std::to_string(columns) +
                            " fields (the recording stopped mid-row); skipped");
        break;
      }
      throw std::invalid_argument(where + ": expected " + std::to_string(columns) +
                                  " fields (as in the header), found " +
                                  std::to_string(fields.size()));
    }
    const double sample = ParseWhole(fields[0], 0, 1e15, where, "Sample:");
    const double hour = ParseWhole(fields[1], 0, 23, where, "Hour");
    const double minute = ParseWhole(fields[2], 0, 59, where, "Minutes");
    const double second = ParseWhole(fields[3], 0, 60, where, "Seconds");
    const double ms = ParseWhole(fields[4], 0, 999, where, "ms");
    if (previous_sample >= 0.0) {
      if (!(sample > previous_sample)) {
        throw std::invalid_argument(where + ": column 'Sample:': sample number " +
                                    FormatNumber(sample) + " is not after " +
                                    FormatNumber(previous_sample));
      }
      missing_samples += static_cast<std::size_t>(sample - previous_sample - 1.0);
    }
    previous_sample = sample;
    double t_s = day_s + 3600.0 * hour + 60.0 * minute + second + 1e-3 * ms;
    if (previous_s >= 0.0 && t_s < previous_s - kDayS / 2) {  // past midnight
      day_s += kDayS;
      t_s += kDayS;
      log.notes.push_back("line " + std::to_string(i + 1) + ": the time of day passed midnight");
    }
    previous_s = t_s;
    Row row{i + 1, t_s, {}};
    row.values.reserve(columns - kAuroraTimeColumns);
    for (std::size_t c = kAuroraTimeColumns; c < columns; ++c) {
      row.values.push_back(ParseField(fields[c], where, std::string(names[c])));
    }
    rows.push_back(std::move(row));
  }

  auto is_zero = [](const Row& r, std::size_t s) {
    const auto first = r.values.begin() + static_cast<std::ptrdiff_t>(s * kAuroraSensorColumns);
    return std::all_of(first, first + kAuroraSensorColumns, [](double v) { return v == 0.0; });
  };
  std::vector<std::size_t> valid(log.sensors.size(), 0);
  for (const Row& r : rows) {
    for (std::size_t s = 0; s < valid.size(); ++s) valid[s] += is_zero(r, s) ? 0 : 1;
  }
  std::size_t chosen = 0;
  if (const auto picked = PickSensor(options.sensor, log.sensors)) {
    if (*picked >= log.sensors.size()) {
      FailFile(path, "no sensor " + Quote(options.sensor) + " (--sensor); the sensors are " +
                         SensorList(log.sensors, valid));
    }
    chosen = *picked;
  } else {
    const auto with_data = std::count_if(valid.begin(), valid.end(), [](auto n) { return n > 0; });
    if (with_data != 1) {
      FailFile(path, std::to_string(with_data) +
                         " sensors have data; choose one with --sensor (index or letter): " +
                         SensorList(log.sensors, valid));
    }
    chosen = static_cast<std::size_t>(
        std::find_if(valid.begin(), valid.end(), [](auto n) { return n > 0; }) - valid.begin());
  }
  log.sensor = log.sensors[chosen];
  EmLogAppender append(log, ResolveUnits(path, options, std::nullopt));
  for (const Row& r : rows) {
    const std::string where = Where(path, r.line);
    if (is_zero(r, chosen)) {
      append.AddDropout(r.t_s, "all zeros", where);
    } else {
      const double* p = r.values.data() + chosen * kAuroraSensorColumns;
      append.AddValid(r.t_s, Eigen::Vector3d(p[0], p[1], p[2]), where);
    }
  }
  append.CountMissing("sample number gap", missing_samples);
  return log;
}

EmLog ReadSimEmLog(const fs::path& path, const EmImportOptions& options) {
  CsvTableSpec spec;
  spec.required = {"t_s", "status"};
  spec.time_column = "t_s";
  spec.text_columns = {"status"};
  spec.min_rows = 1;
  spec.what = "an EM log";
  const CsvTable table = ReadCsvTable(path, spec);
  std::optional<LengthUnit> file_units;
  for (const LengthUnit unit : {LengthUnit::kMillimetre, LengthUnit::kInch}) {
    const std::string suffix = std::string("_") + LengthUnitName(unit);
    const bool has = table.Index("x" + suffix) < table.names.size() &&
                     table.Index("y" + suffix) < table.names.size() &&
                     table.Index("z" + suffix) < table.names.size();
    if (has && file_units) FailFile(path, "line 1: both x_mm,y_mm,z_mm and x_in,y_in,z_in columns");
    if (has) file_units = unit;
  }
  if (!file_units) {
    FailFile(path,
             "line 1: missing position columns x_mm,y_mm,z_mm (or x_in,y_in,z_in for inches)");
  }
  const std::string suffix = std::string("_") + LengthUnitName(*file_units);
  const auto& t = table.values[table.Index("t_s")];
  const auto& x = table.values[table.Index("x" + suffix)];
  const auto& y = table.values[table.Index("y" + suffix)];
  const auto& z = table.values[table.Index("z" + suffix)];
  const auto& status = table.text[table.Index("status")];
  EmLog log;
  log.source = path;
  log.format = EmLogFormat::kSim;
  log.sensor = "tip";
  log.sensors = {"tip"};
  EmLogAppender append(log, ResolveUnits(path, options, file_units));
  for (std::size_t i = 0; i < t.size(); ++i) {
    const std::string where = Where(path, table.lines[i]);
    if (status[i] == "OK") {
      append.AddValid(t[i], Eigen::Vector3d(x[i], y[i], z[i]), where);
    } else if (status[i] == "MISSING" || status[i] == "INVALID" || status[i] == "OUT_OF_VIEW" ||
               status[i] == "OUT_OF_VOLUME") {
      append.AddDropout(t[i], status[i], where);
    } else {
      throw std::invalid_argument(where + ": column 'status': " + Quote(status[i]) +
                                  " is not OK, MISSING, INVALID, OUT_OF_VIEW or OUT_OF_VOLUME");
    }
  }
  return log;
}

std::string SimEmLogHeader() { return "t_s,x_mm,y_mm,z_mm,status"; }

std::string SimEmLogRow(const EmSample& sample) {
  std::string row;
  csv::AppendNumber(row, sample.t_s);
  for (int k = 0; k < 3; ++k) {
    row += ',';
    csv::AppendNumber(row, sample.valid ? sample.position_mm[k] : 0.0);
  }
  row += sample.valid ? ",OK" : ",MISSING";
  return row;
}

}  // namespace echoservo::formats
