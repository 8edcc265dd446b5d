#include "formats/csv_table.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <unordered_set>

namespace echoservo::formats {
namespace {

namespace fs = std::filesystem;

constexpr std::size_t kMaxQuotedChars = 32;  // longer offending fields are truncated

[[noreturn]] void FailLine(const fs::path& file, std::size_t line, const std::string& why) {
  FailFile<CsvFormatError>(file, "line " + std::to_string(line) + ": " + why);
}

}  // namespace

namespace csv {

std::string_view Trim(std::string_view s) {
  constexpr std::string_view kSpace = " \t\r\n\v\f";
  const std::size_t b = s.find_first_not_of(kSpace);
  if (b == std::string_view::npos) return {};
  const std::size_t e = s.find_last_not_of(kSpace);
  return s.substr(b, e - b + 1);
}

// `"text"` with non-printable bytes escaped and long text truncated, for error messages.
std::string Quote(std::string_view s) {
  std::string out = "\"";
  const std::size_t n = std::min(s.size(), kMaxQuotedChars);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c < 0x20 || c >= 0x7F) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02X", static_cast<unsigned>(c));
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  out += '"';
  if (s.size() > n) out += "... (" + std::to_string(s.size()) + " bytes, truncated)";
  return out;
}

// Locale-independent strict parse: the whole (trimmed) field must be one decimal number.
NumberStatus ParseNumber(std::string_view s, double& out) {
  if (s.size() >= 2 && s.front() == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  if (s.empty()) return NumberStatus::kNotANumber;
  const char* end = s.data() + s.size();
  const auto [ptr, ec] = std::from_chars(s.data(), end, out, std::chars_format::general);
  if (ec == std::errc::result_out_of_range && ptr == end) return NumberStatus::kOutOfRange;
  if (ec != std::errc() || ptr != end) return NumberStatus::kNotANumber;
  if (!std::isfinite(out)) return NumberStatus::kNonFinite;
  return NumberStatus::kOk;
}

// Shortest decimal text that parses back to exactly `v` (std::to_chars round-trip form).
void AppendNumber(std::string& out, double v) {
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, v);
  if (ec != std::errc()) throw std::runtime_error("trial writer: cannot format a number");
  out.append(buf, ptr);
}

std::string FormatNumber(double v) {
  std::string s;
  AppendNumber(s, v);
  return s;
}

}  // namespace csv

using csv::FormatNumber;
using csv::NumberStatus;
using csv::ParseNumber;
using csv::Quote;
using csv::Trim;

std::size_t CsvTable::Index(std::string_view name) const {
  return static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
}

CsvTable ReadCsvTable(const fs::path& path, const CsvTableSpec& spec) {
  std::ifstream in(path, std::ios::binary);
  if (!in) FailFile<CsvFormatError>(path, "cannot open file for reading");

  CsvTable csv;
  std::vector<std::string_view> fields;  // sized from the header, i.e. from bytes actually read
  std::string line;
  std::size_t line_no = 0;
  bool have_header = false;
  std::size_t t_col = 0;
  std::optional<std::size_t> blank_line;  // first blank line after the header, if any
  std::size_t prev_line_no = 0;           // line of the previous sample
  std::vector<bool> is_text;              // per column: kept as text

  while (std::getline(in, line)) {
    ++line_no;
    std::string_view view = line;
    if (line_no == 1 && view.starts_with(kUtf8Bom)) view.remove_prefix(kUtf8Bom.size());
    if (!view.empty() && view.back() == '\r') view.remove_suffix(1);

    if (!have_header) {
      if (Trim(view).empty()) {
        // Blank lines may only trail the data; a leading one means no header line.
        continue;
      }
      if (line_no != 1) {
        FailLine(path, line_no,
                 "the header line must be the first line (found blank lines before it)");
      }
      std::unordered_set<std::string_view> seen;  // views into `line`, alive for this block
      std::size_t pos = 0;
      while (true) {
        const std::size_t comma = view.find(',', pos);
        const std::string_view name = Trim(view.substr(
            pos, comma == std::string_view::npos ? std::string_view::npos : comma - pos));
        const std::size_t index = csv.names.size() + 1;
        if (name.empty()) {
          FailLine(path, line_no,
                   "column " + std::to_string(index) + " of the header has an empty name");
        }
        if (!seen.insert(name).second) {
          FailLine(
              path, line_no,
              "duplicate column name " + Quote(name) + " (column " + std::to_string(index) + ")");
        }
        csv.names.emplace_back(name);
        if (comma == std::string_view::npos) break;
        pos = comma + 1;
      }
      std::string missing;
      std::size_t n_missing = 0;
      std::vector<std::string> required = spec.required;
      if (std::find(required.begin(), required.end(), spec.time_column) == required.end()) {
        required.insert(required.begin(), spec.time_column);
      }
      for (const std::string& req : required) {
        if (!seen.contains(req)) {
          missing += (n_missing++ ? ", '" : "'") + req + "'";
        }
      }
      if (n_missing > 0) {
        FailLine(
            path, line_no,
            std::string(n_missing == 1 ? "missing required column " : "missing required columns ") +
                missing + (spec.required_hint.empty() ? "" : " " + spec.required_hint));
      }
      t_col = static_cast<std::size_t>(
          std::find(csv.names.begin(), csv.names.end(), spec.time_column) - csv.names.begin());
      csv.values.resize(csv.names.size());
      csv.text.resize(csv.names.size());
      is_text.assign(csv.names.size(), false);
      for (const std::string& name : spec.text_columns) {
        const std::size_t c = csv.Index(name);
        if (c < csv.names.size() && c != t_col) is_text[c] = true;
      }
      fields.resize(csv.names.size());
      have_header = true;
      continue;
    }

    if (Trim(view).empty()) {
      if (!blank_line) blank_line = line_no;
      continue;
    }
    if (blank_line) {
      FailLine(path, *blank_line,
               "empty line inside the data (only trailing empty lines are allowed)");
    }

    // Split without allocating per field; stop counting into `fields` once it is full.
    std::size_t count = 0;
    std::size_t pos = 0;
    while (true) {
      const std::size_t comma = view.find(',', pos);
      if (count < fields.size()) {
        fields[count] = view.substr(
            pos, comma == std::string_view::npos ? std::string_view::npos : comma - pos);
      }
      ++count;
      if (comma == std::string_view::npos) break;
      pos = comma + 1;
    }
    if (count != fields.size()) {
      FailLine(path, line_no,
               "expected " + std::to_string(fields.size()) + " fields (as in the header), found " +
                   std::to_string(count));
    }

    for (std::size_t c = 0; c < fields.size(); ++c) {
      const std::string_view field = Trim(fields[c]);
      if (is_text[c]) {
        csv.text[c].emplace_back(field);
        continue;
      }
      double v = 0.0;
      const NumberStatus status = ParseNumber(field, v);
      if (status != NumberStatus::kOk) {
        const std::string column = "column '" + csv.names[c] + "': ";
        switch (status) {
          case NumberStatus::kNonFinite:
            FailLine(path, line_no, column + "NaN or infinity is not allowed: " + Quote(field));
          case NumberStatus::kOutOfRange:
            FailLine(path, line_no,
                     column + "number out of the range of a double: " + Quote(field));
          default:
            FailLine(path, line_no, column + "not a number: " + Quote(field));
        }
      }
      if (c == t_col && !csv.values[c].empty() && !(v > csv.values[c].back())) {
        FailLine(path, line_no,
                 "column '" + spec.time_column + "': times must be strictly increasing (t = " +
                     FormatNumber(v) + " s is not after t = " + FormatNumber(csv.values[c].back()) +
                     " s on line " + std::to_string(prev_line_no) + ")");
      }
      csv.values[c].push_back(v);
    }
    csv.lines.push_back(line_no);
    prev_line_no = line_no;
  }
  if (in.bad()) FailFile<CsvFormatError>(path, "read error");
  if (!have_header) FailFile<CsvFormatError>(path, "empty file (no header line)");
  const std::size_t samples = csv.lines.size();
  if (samples < spec.min_rows) {
    FailFile<CsvFormatError>(path, "has " + std::to_string(samples) + " sample(s); " + spec.what +
                                       " needs at least " + std::to_string(spec.min_rows));
  }
  return csv;
}

}  // namespace echoservo::formats
