// Strict reader of numeric CSV tables with a header line, shared by the trial format
// (formats/trial_io.h) and target-motion traces (estimation/motion_trace.h).
//
// Every cell must be one finite decimal number (NaN and infinity are rejected) except in
// the columns the spec names as text, every
// row has as many fields as the header, the time column is strictly increasing, blank
// lines may only trail the data. A bad file throws CsvFormatError naming the file, the
// line, the column and why. Units are whatever the caller's format says.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace echoservo::formats {

// The UTF-8 byte-order mark that spreadsheet programs put before a CSV header.
inline constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";

// Throws E("<file>: <why>"): every reader's errors name the file first.
template <class E = std::invalid_argument>
[[noreturn]] void FailFile(const std::filesystem::path& file, const std::string& why) {
  throw E(file.string() + ": " + why);
}

class CsvFormatError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

struct CsvTableSpec {
  std::vector<std::string> required;  // columns that must be in the header
  std::string required_hint;          // appended to a missing-column error, e.g. "(required: …)"
  std::string time_column = "t";      // must be present and strictly increasing
  // Columns kept as text (trimmed, any content but a comma), e.g. a status or mode label;
  // they must be in `required` or the header to be read.
  std::vector<std::string> text_columns;
  std::size_t min_rows = 2;
  std::string what = "a table";  // "…; <what> needs at least <min_rows>"
};

struct CsvTable {
  std::vector<std::string> names;              // in file order
  std::vector<std::vector<double>> values;     // one vector per column (empty for text)
  std::vector<std::vector<std::string>> text;  // one vector per text column (else empty)
  std::vector<std::size_t> lines;              // file line of every row

  // Index of column `name` in `names`, or names.size() when absent.
  std::size_t Index(std::string_view name) const;
};

// Throws CsvFormatError.
CsvTable ReadCsvTable(const std::filesystem::path& path, const CsvTableSpec& spec);

// Text helpers for readers and their error messages.
namespace csv {
std::string_view Trim(std::string_view s);
// `"text"` with non-printable bytes escaped and long text truncated.
std::string Quote(std::string_view s);
enum class NumberStatus { kOk, kNotANumber, kNonFinite, kOutOfRange };
// Locale-independent strict parse: the whole (trimmed) field must be one decimal number.
NumberStatus ParseNumber(std::string_view s, double& out);
// Shortest decimal text that parses back to exactly `v`.
void AppendNumber(std::string& out, double v);
std::string FormatNumber(double v);
}  // namespace csv

}  // namespace echoservo::formats
