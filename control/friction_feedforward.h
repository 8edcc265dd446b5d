// Friction (and inertia) feed-forward for the base position loop.
//
// F_ff = F_c·tanh(v/v_ε) + b·v + m·a, evaluated on the shaped setpoint's velocity v
// (mm/s) and acceleration a (mm/s²), so the PID only corrects what the model misses.
// F_c (N) and b (N/(mm/s)) come from calibration (control/experiments/calibration.h); m (kg) is
// the slide's moving mass; v_ε smooths the Coulomb sign change through zero speed.
#pragma once

#include "formats/parameter_spec.h"

namespace echoservo::control {

// The feed-forward's tunable terms (formats/parameter_spec.h): declared once, read by
// Validate and by the pipeline's registry (stage "servo"; calibration measures them).
namespace params {
inline constexpr formats::ParameterSpec kCoulombFfN{
    "servo.coulomb_ff_n",
    "N",
    formats::ParameterKind::kReal,
    0,
    5,
    0.0,
    "friction feed-forward: Coulomb term (calibration measures it; the simulated catheter's "
    "nominal friction)"};
inline constexpr formats::ParameterSpec kViscousFfNPerMmS{
    "servo.viscous_ff_n_per_mm_s",        "N/(mm/s)", formats::ParameterKind::kReal, 0, 0.1, 0.0,
    "friction feed-forward: viscous term"};
}  // namespace params

struct FrictionFeedforward {
  double coulomb_n = params::kCoulombFfN.default_value;
  double viscous_n_per_mm_s = params::kViscousFfNPerMmS.default_value;
  double moving_mass_kg = 0.0;
  double sign_smoothing_mm_s = 2.0;
  // Throws std::invalid_argument naming the field for negative or non-finite values.
  void Validate() const;
  double ForceN(double velocity_mm_s, double acceleration_mm_s2) const;
};

}  // namespace echoservo::control
