// A fixed-rate delay line: push one sample every `sample_period_s`, read the value
// `delay_s` ago with linear interpolation. Used for the tip sensor latency.
#pragma once

#include <cstddef>
#include <vector>

namespace echoservo::hw {

class DelayLine {
 public:
  // Throws std::invalid_argument for a non-positive period or a negative delay.
  DelayLine(double sample_period_s, double max_delay_s);
  void Reset(double value);
  void Push(double value);
  // Value `delay_s` (0 ≤ delay ≤ max_delay) before the newest sample.
  double Delayed(double delay_s) const;

 private:
  double period_s_;
  std::vector<double> ring_;
  std::size_t newest_ = 0;
};

}  // namespace echoservo::hw
