#include "hw/delay_line.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace echoservo::hw {

DelayLine::DelayLine(double sample_period_s, double max_delay_s) : period_s_(sample_period_s) {
  if (!(sample_period_s > 0.0) || !(max_delay_s >= 0.0) || !std::isfinite(max_delay_s)) {
    throw std::invalid_argument("delay line: period must be > 0 and max delay >= 0");
  }
  ring_.assign(static_cast<std::size_t>(std::ceil(max_delay_s / sample_period_s)) + 2, 0.0);
}

void DelayLine::Reset(double value) { std::fill(ring_.begin(), ring_.end(), value); }

void DelayLine::Push(double value) {
  newest_ = (newest_ + 1) % ring_.size();
  ring_[newest_] = value;
}

double DelayLine::Delayed(double delay_s) const {
  const double steps = std::clamp(delay_s / period_s_, 0.0, static_cast<double>(ring_.size() - 2));
  const auto whole = static_cast<std::size_t>(steps);
  const double frac = steps - static_cast<double>(whole);
  const std::size_t n = ring_.size();
  const double a = ring_[(newest_ + n - whole) % n];
  const double b = ring_[(newest_ + n - whole - 1) % n];
  return a + frac * (b - a);
}

}  // namespace echoservo::hw
