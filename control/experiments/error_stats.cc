#include "control/experiments/error_stats.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace echoservo::control {

ErrorStats ComputeErrorStats(const std::vector<double>& error) {
  if (error.empty()) throw std::invalid_argument("error statistics of an empty signal");
  ErrorStats s;
  double sum_abs = 0.0;
  double sum_sq = 0.0;
  for (double e : error) {
    if (!std::isfinite(e)) throw std::invalid_argument("error statistics: non-finite sample");
    sum_abs += std::abs(e);
    sum_sq += e * e;
    s.max_abs_mm = std::max(s.max_abs_mm, std::abs(e));
  }
  s.samples = error.size();
  s.mae_mm = sum_abs / static_cast<double>(s.samples);
  s.rms_mm = std::sqrt(sum_sq / static_cast<double>(s.samples));
  return s;
}

}  // namespace echoservo::control
