// Summary statistics of a tracking error signal (mm): MAE, RMS, max |e|.
#pragma once

#include <cstddef>
#include <vector>

namespace echoservo::control {

struct ErrorStats {
  double mae_mm = 0.0;
  double rms_mm = 0.0;
  double max_abs_mm = 0.0;
  std::size_t samples = 0;
};

// Throws std::invalid_argument on an empty or non-finite input.
ErrorStats ComputeErrorStats(const std::vector<double>& error);

}  // namespace echoservo::control
