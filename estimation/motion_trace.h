// A target-motion trace: time-stamped positions of the target along the catheter axis
// (time in s, position in mm), the input of `echoservo predict` and of the motion lab.
//
// File format: a CSV with a header line, a time column `t` (s, strictly increasing) and
// one or more position columns (mm); one column is chosen by name (default: the first
// after `t`). NaN, infinity, non-numeric cells, duplicate or decreasing times are errors
// naming the file, line and column (formats/csv_table.h). Gaps — intervals longer than
// `kGapFactor` times the median interval — are allowed: predictors coast through them.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace echoservo::estimation {

// An interval longer than this many median intervals is a gap (missing frames).
inline constexpr double kGapFactor = 2.5;

struct MotionTrace {
  std::string source;  // file path, or a description for generated traces
  std::string column;  // position column name
  std::vector<double> t_s;
  std::vector<double> position_mm;
  std::vector<std::size_t> lines;  // file line of each sample; empty for generated traces

  std::size_t size() const { return t_s.size(); }
  double duration_s() const { return t_s.empty() ? 0.0 : t_s.back() - t_s.front(); }
  // "file:line" of sample i when read from a file, else "sample i".
  std::string Where(std::size_t i) const;
};

// Reads `column` (empty: the first column after `t`). Throws std::invalid_argument.
MotionTrace ReadMotionTrace(const std::filesystem::path& path, const std::string& column = "");

// Checks an in-memory trace: equal lengths, at least 2 samples, finite values, strictly
// increasing times. Throws std::invalid_argument naming the sample.
void ValidateMotionTrace(const MotionTrace& trace);

double MedianInterval(const MotionTrace& trace);
// Indices i where (t[i-1], t[i]) is a gap.
std::vector<std::size_t> FindGaps(const MotionTrace& trace);

// Linear interpolation at t; false (and `out` untouched) outside the trace or inside a gap.
// Each call finds the trace's gaps again (O(n)): interpolate one trace many times with
// TraceInterpolator.
bool InterpolateTrace(const MotionTrace& trace, double t_s, double& out);

// InterpolateTrace for many times on one trace: the gap limit (from the median sampling
// interval) is found once. The trace must outlive the interpolator and stay unchanged.
class TraceInterpolator {
 public:
  explicit TraceInterpolator(const MotionTrace& trace);
  // As InterpolateTrace(trace, t_s, out).
  bool At(double t_s, double& out) const;

 private:
  const MotionTrace& trace_;
  double gap_limit_s_;
};

// Measurements at `rate_hz` (t0 + k/rate, linear interpolation), skipping times that fall
// outside the trace or inside gaps. Throws std::invalid_argument for a rate that is not
// finite and positive.
MotionTrace ResampleTrace(const MotionTrace& trace, double rate_hz);

}  // namespace echoservo::estimation
