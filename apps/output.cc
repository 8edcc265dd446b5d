#include "apps/output.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <stdexcept>

namespace echoservo::apps {

void Table::Print(std::ostream& out) const {
  std::vector<std::size_t> width(header_.size(), 0);
  auto widen = [&](const std::vector<std::string>& row) {
    for (std::size_t i = 0; i < row.size() && i < width.size(); ++i)
      width[i] = std::max(width[i], row[i].size());
  };
  widen(header_);
  for (const auto& r : rows_) widen(r);
  auto line = [&](const std::vector<std::string>& row) {
    for (std::size_t i = 0; i < row.size() && i < width.size(); ++i) {
      out << (i == 0 ? "" : "  ") << std::setw(static_cast<int>(width[i]))
          << (i == 0 ? std::left : std::right) << row[i];
    }
    out << std::right << "\n";
  };
  line(header_);
  std::size_t total = 0;
  for (std::size_t w : width) total += w + 2;
  out << std::string(total > 2 ? total - 2 : 0, '-') << "\n";
  for (const auto& r : rows_) line(r);
}

void WriteFileAtomically(const std::string& path, const std::string& text) {
  const std::filesystem::path target(path);
  const std::filesystem::path tmp = target.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot write " + tmp.string());
    out << text;
    out.close();
    if (!out) throw std::runtime_error("error writing " + tmp.string());
  }
  std::filesystem::rename(tmp, target);
}

std::string Fixed(double value, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
  return buf;
}

namespace {
double ParseNumber(const std::string& text, const std::string& where) {
  double v = 0.0;
  const char* first = text.data();
  const char* last = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(first, last, v);
  if (text.empty() || ec != std::errc() || ptr != last || !std::isfinite(v)) {
    throw std::invalid_argument(where + ": '" + text + "' is not a finite number");
  }
  return v;
}
}  // namespace

std::pair<std::string, double> ParseAssignment(const std::string& text) {
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0 || text.find('.') > eq) {
    throw std::invalid_argument("--set '" + text + "': expected <effect>.<parameter>=<value>");
  }
  return {text.substr(0, eq), ParseNumber(text.substr(eq + 1), "--set " + text.substr(0, eq))};
}

std::vector<std::string> SplitList(const std::string& text, const std::string& option) {
  std::vector<std::string> items;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, end - start);
    if (item.empty()) throw std::invalid_argument(option + ": empty item in '" + text + "'");
    items.push_back(item);
    start = end + 1;
  }
  return items;
}

std::vector<double> ParseNumberList(const std::string& text, const std::string& option) {
  std::vector<double> values;
  for (const std::string& item : SplitList(text, option))
    values.push_back(ParseNumber(item, option));
  return values;
}

}  // namespace echoservo::apps
