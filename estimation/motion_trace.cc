#include "estimation/motion_trace.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "formats/csv_table.h"

namespace echoservo::estimation {

std::string MotionTrace::Where(std::size_t i) const {
  if (i < lines.size()) return source + ":" + std::to_string(lines[i]);
  return source + ": sample " + std::to_string(i);
}

MotionTrace ReadMotionTrace(const std::filesystem::path& path, const std::string& column) {
  formats::CsvTableSpec spec;
  spec.time_column = "t";
  if (!column.empty()) spec.required = {column};
  spec.required_hint = "(a motion trace needs a time column 't' and position columns in mm)";
  spec.min_rows = 2;
  spec.what = "a motion trace";
  formats::CsvTable table = formats::ReadCsvTable(path, spec);
  const auto t_it = std::find(table.names.begin(), table.names.end(), "t");
  std::size_t col = table.names.size();
  if (column.empty()) {
    for (std::size_t c = 0; c < table.names.size(); ++c) {
      if (table.names[c] != "t") {
        col = c;
        break;
      }
    }
    if (col == table.names.size()) {
      throw std::invalid_argument(path.string() +
                                  ": line 1: no position column (only 't'); a motion trace needs "
                                  "a time column 't' and position columns in mm");
    }
  } else {
    col = static_cast<std::size_t>(std::find(table.names.begin(), table.names.end(), column) -
                                   table.names.begin());
    if (table.names[col] == "t") {
      throw std::invalid_argument(path.string() + ": --column 't' is the time column");
    }
  }
  MotionTrace trace;
  trace.source = path.string();
  trace.column = table.names[col];
  trace.t_s = std::move(table.values[static_cast<std::size_t>(t_it - table.names.begin())]);
  trace.position_mm = std::move(table.values[col]);
  trace.lines = std::move(table.lines);
  return trace;
}

void ValidateMotionTrace(const MotionTrace& trace) {
  if (trace.t_s.size() != trace.position_mm.size()) {
    throw std::invalid_argument(trace.source + ": time and position counts differ");
  }
  if (trace.size() < 2) {
    throw std::invalid_argument(trace.source + ": has " + std::to_string(trace.size()) +
                                " sample(s); a motion trace needs at least 2");
  }
  for (std::size_t i = 0; i < trace.size(); ++i) {
    if (!std::isfinite(trace.t_s[i]) || !std::isfinite(trace.position_mm[i])) {
      throw std::invalid_argument(trace.Where(i) + ": NaN or infinity is not allowed");
    }
    if (i > 0 && !(trace.t_s[i] > trace.t_s[i - 1])) {
      throw std::invalid_argument(trace.Where(i) + ": times must be strictly increasing");
    }
  }
}

double MedianInterval(const MotionTrace& trace) {
  if (trace.size() < 2) return 0.0;
  std::vector<double> dt(trace.size() - 1);
  for (std::size_t i = 1; i < trace.size(); ++i) dt[i - 1] = trace.t_s[i] - trace.t_s[i - 1];
  const auto mid = dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2);
  std::nth_element(dt.begin(), mid, dt.end());
  return *mid;
}

std::vector<std::size_t> FindGaps(const MotionTrace& trace) {
  std::vector<std::size_t> gaps;
  const double limit = kGapFactor * MedianInterval(trace);
  for (std::size_t i = 1; i < trace.size(); ++i) {
    if (trace.t_s[i] - trace.t_s[i - 1] > limit) gaps.push_back(i);
  }
  return gaps;
}

namespace {

bool Interpolate(const MotionTrace& trace, double limit, double t_s, double& out) {
  if (trace.size() < 2 || t_s < trace.t_s.front() || t_s > trace.t_s.back()) return false;
  const auto it = std::lower_bound(trace.t_s.begin(), trace.t_s.end(), t_s);
  const auto i = static_cast<std::size_t>(it - trace.t_s.begin());
  if (trace.t_s[i] == t_s) {
    out = trace.position_mm[i];
    return true;
  }
  const double t0 = trace.t_s[i - 1];
  const double t1 = trace.t_s[i];
  if (t1 - t0 > limit) return false;
  const double u = (t_s - t0) / (t1 - t0);
  out = trace.position_mm[i - 1] + u * (trace.position_mm[i] - trace.position_mm[i - 1]);
  return true;
}

}  // namespace

bool InterpolateTrace(const MotionTrace& trace, double t_s, double& out) {
  return TraceInterpolator(trace).At(t_s, out);
}

TraceInterpolator::TraceInterpolator(const MotionTrace& trace)
    : trace_(trace), gap_limit_s_(kGapFactor * MedianInterval(trace)) {}

bool TraceInterpolator::At(double t_s, double& out) const {
  return Interpolate(trace_, gap_limit_s_, t_s, out);
}

MotionTrace ResampleTrace(const MotionTrace& trace, double rate_hz) {
  if (!(std::isfinite(rate_hz) && rate_hz > 0.0)) {
    throw std::invalid_argument("--rate must be a finite positive number of Hz");
  }
  MotionTrace out;
  out.source = trace.source;
  out.column = trace.column;
  const double limit = kGapFactor * MedianInterval(trace);
  const double step = 1.0 / rate_hz;
  const auto n = static_cast<std::size_t>(std::floor(trace.duration_s() / step + 1e-9));
  for (std::size_t k = 0; k <= n; ++k) {
    const double t = trace.t_s.front() + static_cast<double>(k) * step;
    double x = 0.0;
    if (Interpolate(trace, limit, std::min(t, trace.t_s.back()), x)) {
      out.t_s.push_back(t);
      out.position_mm.push_back(x);
    }
  }
  return out;
}

}  // namespace echoservo::estimation
