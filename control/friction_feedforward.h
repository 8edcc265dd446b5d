// Friction (and inertia) feed-forward for the base position loop.
//
// F_ff = F_c·tanh(v/v_ε) + b·v + m·a, evaluated on the shaped setpoint's velocity v
// (mm/s) and acceleration a (mm/s²), so the PID only corrects what the model misses.
// F_c (N) and b (N/(mm/s)) come from calibration (control/experiments/calibration.h); m (kg) is
// the slide's moving mass; v_ε smooths the Coulomb sign change through zero speed.
#pragma once

namespace echoservo::control {

struct FrictionFeedforward {
  double coulomb_n = 0.0;
  double viscous_n_per_mm_s = 0.0;
  double moving_mass_kg = 0.0;
  double sign_smoothing_mm_s = 2.0;
  // Throws std::invalid_argument naming the field for negative or non-finite values.
  void Validate() const;
  double ForceN(double velocity_mm_s, double acceleration_mm_s2) const;
};

}  // namespace echoservo::control
