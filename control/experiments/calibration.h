// Calibration from short probing motions, as the seed did before each experiment.
//
// Runs through any HardwareInterface (simulated or real) under the base servo without
// compensation: constant-velocity strokes at several speeds give force–velocity samples
// (mean force-sensor reading over the steady middle of each stroke) fitted with the
// Coulomb + viscous law; a slow sine on the base gives the hysteresis width between
// base and tip (control/experiments/hysteresis.h). The results seed the friction feed-forward and
// the backlash inverse. Units: mm, s, N.
#pragma once

#include <vector>

#include "control/experiments/friction_fit.h"
#include "control/experiments/hysteresis.h"
#include "control/servo_loop.h"

namespace echoservo::control {

struct ProbeOptions {
  std::vector<double> speeds_mm_s = {5.0, 10.0, 20.0, 40.0, 80.0};
  double stroke_amplitude_mm = 6.0;    // triangle between ±amplitude
  int strokes_per_speed = 2;           // full triangle periods per speed
  double backlash_amplitude_mm = 5.0;  // the seed's 5 mm, 1 Hz sine
  double backlash_frequency_hz = 1.0;
  int backlash_cycles = 3;  // the first is discarded
  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

struct CalibrationResult {
  std::vector<FrictionSample> friction_samples;
  FrictionFit friction;
  HysteresisWidth backlash;
};

// The hardware must be active. `servo` is used as given (feed-forward is switched off).
std::vector<FrictionSample> ProbeFriction(hw::HardwareInterface& hardware, ServoConfig servo,
                                          const ProbeOptions& options);
HysteresisWidth ProbeBacklash(hw::HardwareInterface& hardware, ServoConfig servo,
                              const ProbeOptions& options);
CalibrationResult Calibrate(hw::HardwareInterface& hardware, const ServoConfig& servo,
                            const ProbeOptions& options = {});

}  // namespace echoservo::control
