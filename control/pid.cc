#include "control/pid.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace echoservo::control {

void PidGains::Validate() const {
  auto check = [](double v, const char* name, bool strictly_positive) {
    if (!std::isfinite(v) || v < 0.0 || (strictly_positive && v == 0.0)) {
      throw std::invalid_argument(std::string("PID gain '") + name + "' must be finite and " +
                                  (strictly_positive ? "> 0" : ">= 0"));
    }
  };
  params::kKpNPerMm.Check(kp_n_per_mm, "PID gains");
  params::kKiNPerMmS.Check(ki_n_per_mm_s, "PID gains");
  params::kKdNPerMmPerS.Check(kd_n_per_mm_per_s, "PID gains");
  check(derivative_cutoff_hz, "derivative_cutoff_hz", true);
  check(output_limit_n, "output_limit_n", true);
}

Pid::Pid(PidGains gains, double period_s) : gains_(gains), period_s_(period_s) {
  gains_.Validate();
  if (!(std::isfinite(period_s) && period_s > 0.0)) {
    throw std::invalid_argument("PID period must be finite and > 0 s");
  }
}

void Pid::Reset(double measurement) {
  integral_ = 0.0;
  derivative_ = 0.0;
  last_measurement_ = measurement;
  saturated_ = false;
  primed_ = true;
}

double Pid::Update(double setpoint, double measurement, double feedforward_n) {
  if (!primed_) Reset(measurement);
  const double error = setpoint - measurement;
  const double raw_rate = (measurement - last_measurement_) / period_s_;
  last_measurement_ = measurement;
  const double alpha =
      1.0 - std::exp(-2.0 * std::numbers::pi * gains_.derivative_cutoff_hz * period_s_);
  derivative_ += alpha * (raw_rate - derivative_);

  const double limit = gains_.output_limit_n;
  const double pd =
      gains_.kp_n_per_mm * error - gains_.kd_n_per_mm_per_s * derivative_ + feedforward_n;
  // Anti-windup: conditional integration (freeze while the output is saturated in the
  // direction the error pushes) and an absolute bound on the integral term.
  const double candidate =
      std::clamp(integral_ + gains_.ki_n_per_mm_s * error * period_s_, -limit, limit);
  const double trial = pd + candidate;
  if (std::abs(trial) <= limit || (trial > 0.0) != (error > 0.0)) integral_ = candidate;
  const double unsaturated = pd + integral_;
  const double out = std::clamp(unsaturated, -limit, limit);
  saturated_ = out != unsaturated;
  return out;
}

}  // namespace echoservo::control
