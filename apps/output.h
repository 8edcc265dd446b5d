// Small helpers shared by the CLI commands: aligned text tables and option parsing.
#pragma once

#include <ostream>
#include <string>
#include <utility>
#include <vector>

namespace echoservo::apps {

class Table {
 public:
  explicit Table(std::vector<std::string> header) : header_(std::move(header)) {}
  void AddRow(std::vector<std::string> row) { rows_.push_back(std::move(row)); }
  void Print(std::ostream& out) const;

 private:
  std::vector<std::string> header_;
  std::vector<std::vector<std::string>> rows_;
};

// printf-style "%.*f" formatting.
std::string Fixed(double value, int decimals);

// Parses "<effect>.<parameter>=<value>" (from --set); throws std::invalid_argument
// naming the option text when malformed or not a finite number.
std::pair<std::string, double> ParseAssignment(const std::string& text);

// Parses a comma-separated list of numbers (from e.g. --tip-loads 0,1,2).
std::vector<double> ParseNumberList(const std::string& text, const std::string& option);
// Writes `text` to `path` through a temporary file and a rename (no half-written report);
// throws std::runtime_error naming the file on I/O errors.
void WriteFileAtomically(const std::string& path, const std::string& text);

// Splits on commas (empty items rejected).
std::vector<std::string> SplitList(const std::string& text, const std::string& option);

}  // namespace echoservo::apps
