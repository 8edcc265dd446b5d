// Discrete PID position controller for the catheter base, run at a fixed period.
//
// u = kp·e + ki·∫e + kd·ė_filtered, with the derivative taken on the measurement
// (no kick on setpoint steps) through a first-order filter, and anti-windup by
// conditional integration: the integrator freezes while the output saturates in the
// direction of the error, and is bounded by ±output_limit. Units: the error
// in mm, the output in N (kp in N/mm, ki in N/(mm·s), kd in N/(mm/s)).
#pragma once

#include "formats/parameter_spec.h"

namespace echoservo::control {

// The position loop's tunable gains (formats/parameter_spec.h): declared once, read by
// Validate and by the pipeline's registry (stage "servo"; a catheter's calibrated gains, e.g.
// control::SeedServoConfig, replace the defaults).
namespace params {
inline constexpr formats::ParameterSpec kKpNPerMm{
    "servo.kp_n_per_mm",
    "N/mm",
    formats::ParameterKind::kReal,
    0,
    100,
    12.0,
    "PID proportional gain of the base position loop (100 N/mm saturates the 26.7 N actuator "
    "at 0.27 mm of error)"};
inline constexpr formats::ParameterSpec kKiNPerMmS{"servo.ki_n_per_mm_s",
                                                   "N/(mm*s)",
                                                   formats::ParameterKind::kReal,
                                                   0,
                                                   5000,
                                                   150.0,
                                                   "PID integral gain of the base position loop"};
inline constexpr formats::ParameterSpec kKdNPerMmPerS{
    "servo.kd_n_per_mm_per_s",
    "N/(mm/s)",
    formats::ParameterKind::kReal,
    0,
    1,
    0.07,
    "PID derivative gain of the base position loop (on the measurement, low-passed)"};
}  // namespace params

struct PidGains {
  double kp_n_per_mm = params::kKpNPerMm.default_value;
  double ki_n_per_mm_s = params::kKiNPerMmS.default_value;
  double kd_n_per_mm_per_s = params::kKdNPerMmPerS.default_value;
  double derivative_cutoff_hz = 300.0;
  double output_limit_n = 26.7;
  // Throws std::invalid_argument naming the gain for a negative or non-finite value.
  void Validate() const;
};

class Pid {
 public:
  explicit Pid(PidGains gains, double period_s);
  void Reset(double measurement);
  // One cycle: returns the saturated output (N). `feedforward_n` is added before
  // saturation and taken into account by the anti-windup.
  double Update(double setpoint, double measurement, double feedforward_n = 0.0);
  double integral() const { return integral_; }
  bool saturated() const { return saturated_; }
  const PidGains& gains() const { return gains_; }

 private:
  PidGains gains_;
  double period_s_;
  double integral_ = 0.0;  // N
  double last_measurement_ = 0.0;
  double derivative_ = 0.0;  // filtered d(measurement)/dt, mm/s
  bool saturated_ = false;
  bool primed_ = false;
};

}  // namespace echoservo::control
