// Writers of bad trial files for the dataset-loading tests: a trial is NAME.csv (header
// line, then t,base_cmd,base,tip,force samples) beside its NAME.json sidecar; these
// corrupt one cell, drop a column, or remove or break the JSON, so that the loader's
// error (file, line, column, problem) and --skip-bad can be checked.
#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <functional>
#include <ostream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace echoservo::testing {

inline std::vector<std::string> ReadLines(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

inline void WriteLines(const std::filesystem::path& p, const std::vector<std::string>& lines) {
  std::ofstream out(p, std::ios::trunc);
  for (const std::string& l : lines) out << l << "\n";
}

// Replaces field `column` (0-based) of CSV line `line` (1-based; the header is line 1).
inline void SetCsvField(const std::filesystem::path& csv, std::size_t line, std::size_t column,
                        const std::string& value) {
  std::vector<std::string> lines = ReadLines(csv);
  std::vector<std::string> fields;
  std::stringstream ss(lines.at(line - 1));
  for (std::string f; std::getline(ss, f, ',');) fields.push_back(f);
  fields.at(column) = value;
  std::string joined;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    if (i > 0) joined.push_back(',');
    joined.append(fields[i]);
  }
  lines[line - 1] = joined;
  WriteLines(csv, lines);
}

// Corrupts the trial whose CSV is given (its sidecar is the same path with .json).
using TrialCorruption = std::function<void(const std::filesystem::path& csv)>;

// Cell (`line`, `column`) set to `value`: a non-number, NaN, or a time out of order.
inline TrialCorruption BadCell(std::size_t line, std::size_t column, std::string value) {
  return [=](const std::filesystem::path& csv) { SetCsvField(csv, line, column, value); };
}

// The last column (`force`) dropped from every line, header included.
inline TrialCorruption MissingLastColumn() {
  return [](const std::filesystem::path& csv) {
    std::vector<std::string> lines = ReadLines(csv);
    for (std::string& l : lines) l = l.substr(0, l.rfind(','));
    WriteLines(csv, lines);
  };
}

inline TrialCorruption MissingJsonSidecar() {
  return [](const std::filesystem::path& csv) {
    std::filesystem::remove(std::filesystem::path(csv).replace_extension(".json"));
  };
}

// The sidecar replaced by `text` (e.g. truncated JSON).
inline TrialCorruption MalformedJsonSidecar(std::string text) {
  return [text = std::move(text)](const std::filesystem::path& csv) {
    std::ofstream(std::filesystem::path(csv).replace_extension(".json"), std::ios::trunc) << text;
  };
}

// One kind of bad trial, as a test parameter.
struct BadTrial {
  const char* name;
  TrialCorruption corrupt;
  std::vector<std::string> expected;  // parts of the error message
};

inline void PrintTo(const BadTrial& b, std::ostream* os) { *os << b.name; }

// Names the instantiated tests after the kind.
inline std::string BadTrialName(const ::testing::TestParamInfo<BadTrial>& info) {
  return info.param.name;
}

// The CSV that sorts first in `dir`, or empty if there is none.
inline std::filesystem::path FirstTrialCsv(const std::filesystem::path& dir) {
  std::filesystem::path first;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() == ".csv" && (first.empty() || e.path() < first)) first = e.path();
  }
  return first;
}

// Copies the trial `csv` (and its sidecar) to `dir`/`name`; returns the new CSV.
inline std::filesystem::path CopyTrial(const std::filesystem::path& csv,
                                       const std::filesystem::path& dir, const std::string& name) {
  const std::filesystem::path to = dir / (name + ".csv");
  std::filesystem::copy_file(csv, to);
  std::filesystem::copy_file(std::filesystem::path(csv).replace_extension(".json"),
                             dir / (name + ".json"));
  return to;
}

}  // namespace echoservo::testing
