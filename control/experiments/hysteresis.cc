#include "control/experiments/hysteresis.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace echoservo::control {

HysteresisWidth EstimateHysteresisWidth(const std::vector<double>& t_s,
                                        const std::vector<double>& base_mm,
                                        const std::vector<double>& tip_mm, double window_s) {
  const std::size_t n = t_s.size();
  if (base_mm.size() != n || tip_mm.size() != n) {
    throw std::invalid_argument("hysteresis: t, base and tip must have the same length");
  }
  if (n < 3) throw std::invalid_argument("hysteresis: need at least 3 samples");
  if (!(window_s > 0.0)) throw std::invalid_argument("hysteresis: window must be > 0 s");
  std::vector<double> v_base(n, 0.0);
  std::vector<double> v_tip(n, 0.0);
  std::size_t lo = 0;
  std::size_t hi = 0;
  double peak = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    while (t_s[i] - t_s[lo] > 0.5 * window_s) ++lo;
    while (hi + 1 < n && t_s[hi + 1] - t_s[i] <= 0.5 * window_s) ++hi;
    const double dt = t_s[hi] - t_s[lo];
    if (dt <= 0.0) continue;
    v_base[i] = (base_mm[hi] - base_mm[lo]) / dt;
    v_tip[i] = (tip_mm[hi] - tip_mm[lo]) / dt;
    peak = std::max(peak, std::abs(v_base[i]));
  }
  HysteresisWidth out;
  double sum_up = 0.0;
  double sum_down = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double vb = v_base[i];
    if (std::abs(vb) < 0.3 * peak) continue;
    if (v_tip[i] * vb <= 0.0 || std::abs(v_tip[i]) < 0.5 * std::abs(vb)) continue;
    if (vb > 0.0) {
      sum_up += base_mm[i] - tip_mm[i];
      ++out.up_samples;
    } else {
      sum_down += base_mm[i] - tip_mm[i];
      ++out.down_samples;
    }
  }
  if (out.up_samples == 0 || out.down_samples == 0) {
    throw std::invalid_argument(
        "hysteresis: the tip never followed the base in both directions (motion smaller than "
        "the deadzone?)");
  }
  out.width_mm = sum_up / static_cast<double>(out.up_samples) -
                 sum_down / static_cast<double>(out.down_samples);
  return out;
}

}  // namespace echoservo::control
