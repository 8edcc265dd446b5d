// Discrete PID position controller for the catheter base, run at a fixed period.
//
// u = kp·e + ki·∫e + kd·ė_filtered, with the derivative taken on the measurement
// (no kick on setpoint steps) through a first-order filter, and anti-windup by
// conditional integration: the integrator freezes while the output saturates in the
// direction of the error, and is bounded by ±output_limit. Units: the error
// in mm, the output in N (kp in N/mm, ki in N/(mm·s), kd in N/(mm/s)).
#pragma once

namespace echoservo::control {

struct PidGains {
  double kp_n_per_mm = 12.0;
  double ki_n_per_mm_s = 150.0;
  double kd_n_per_mm_per_s = 0.07;
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
