// The seed's bench sweeps (Kesner & Howe 2010, §IV) on the simulated catheter.
//
// Friction: for every configuration, constant-velocity strokes in both directions at
// several speeds; the force–velocity samples and the fitted Coulomb and viscous terms.
// Backlash: a 5 mm, 1 Hz sine on the base for every configuration; the measured
// hysteresis width against the seed's model B = θ·gap, with the model's RMS error
// and r² over the sweep (the seed's Fig. 10: RMS 0.4 mm, r² 0.93).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "control/experiments/calibration.h"
#include "hw/simulated_catheter.h"

namespace echoservo::control {

struct SweepOptions {
  std::vector<std::string> effects;                        // empty: the experiment's default plant
  std::vector<std::pair<std::string, double>> parameters;  // "<effect>.<param>" overrides
  double tip_load_n = 0.0;
  std::uint64_t seed = 1;
  ProbeOptions probe;
};

struct FrictionConfigResult {
  formats::CatheterConfig config;
  std::vector<FrictionSample> samples;
  FrictionFit fit;
};

// Default plant: the seed-calibrated effects (friction grows with bend angle through
// the capstan effect).
std::vector<FrictionConfigResult> RunFrictionSweep(const SweepOptions& options);

struct BacklashConfigResult {
  formats::CatheterConfig config;
  double measured_width_mm = 0.0;
  double model_width_mm = 0.0;  // θ·gap
};

struct BacklashSweepResult {
  std::vector<BacklashConfigResult> configs;
  double rms_error_mm = 0.0;  // of θ·gap against the measured widths
  double r2 = 0.0;            // 1 − SS_res/SS_tot of θ·gap as a predictor
};

// Default plant: only the seed's model effects (coulomb, viscous, backlash).
BacklashSweepResult RunBacklashSweep(const SweepOptions& options);

// The plant used by a sweep for one configuration.
hw::PlantOptions SweepPlant(const SweepOptions& options, const formats::CatheterConfig& config,
                            bool seed_model_default);

}  // namespace echoservo::control
