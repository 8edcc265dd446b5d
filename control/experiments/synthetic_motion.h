// Synthetic target-motion traces: the mitral annulus along the catheter axis
// (control/trajectory.h, docs/mitral_trajectory.md) with heart-rate variability,
// respiration and measurement noise — the test traces of the heartbeat predictor
// (docs/predictor.md) and of the motion lab.
//
// The cardiac phase integrates the instantaneous heart rate
//   f(t) = f₀ + linear drift + respiratory sinus arrhythmia (RSA, at the breathing
//          rate) + an Ornstein–Uhlenbeck wander (σ, correlation time τ),
// the position is the mitral shape at that phase, plus respiration
// r·sin(2π·f_r·t + φ_r) (mm), plus white Gaussian noise σ_n (mm). Deterministic for a
// seed. Units: s, Hz, bpm, mm.
#pragma once

#include <cstdint>
#include <vector>

#include "estimation/motion_trace.h"

namespace echoservo::control {

struct SyntheticMotionOptions {
  double duration_s = 40.0;
  double sample_rate_hz = 250.0;
  double heart_rate_bpm = 72.0;
  double peak_to_peak_mm = 12.0;
  int harmonics = 10;
  double rate_drift_bpm_per_min = 0.0;  // linear change of the heart rate
  double rsa_bpm = 0.0;                 // respiratory sinus arrhythmia amplitude
  double wander_bpm = 0.0;              // Ornstein–Uhlenbeck σ of the heart rate
  double wander_tau_s = 8.0;
  double respiration_mm = 0.0;  // amplitude of the respiratory displacement
  double respiration_hz = 0.25;
  double noise_mm = 0.0;
  std::uint64_t seed = 1;
};

struct SyntheticMotion {
  estimation::MotionTrace measured;  // with noise
  std::vector<double> truth_mm;      // noise-free position at the same times
  std::vector<double> heart_rate_bpm;
};

// The defaults of the predictor's test trace: 72 bpm, 12 mm, RSA ±3 bpm, wander 3 bpm,
// 0.3 mm noise (respiration off unless `respiration_mm` is set).
SyntheticMotionOptions MitralHrvDefaults();

// Throws std::invalid_argument for out-of-range options.
SyntheticMotion MakeSyntheticMotion(const SyntheticMotionOptions& options);

}  // namespace echoservo::control
