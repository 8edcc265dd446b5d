// Target-motion models for the model lab: what `lab compare|diagnose` fit to a motion
// trace (estimation/motion_trace.h), the counterpart of the catheter's effect SPECs.
//
// SPEC: "heartbeat:N" (offset + N harmonics of a constant heart rate) followed by
// "+effect" terms from the motion catalog:
//   respiration  r_c·cos(2π f_r τ) + r_s·sin(2π f_r τ), f_r ∈ [0.08, 0.7] Hz
//   rate_drift   the heart rate changes linearly: phase 2π(f τ + ḟ τ²/2)
//   harmonic     one more harmonic (heartbeat:N → heartbeat:N+1)
// with τ = t − (middle of the trace). x(τ) = c + Σ_k a_k cos kφ + b_k sin kφ [+ resp].
// Fit: Ceres (automatic derivatives) on a subset of samples, residuals divided by the
// noise σ; started from a rate search (estimation/harmonic_fit.h) on the middle third,
// then widened to two thirds and the whole trace so a drifting rate is followed.
// Standard deviations from ceres::Covariance scaled by the reduced χ². Units: s, Hz, mm.
#pragma once

#include <string>
#include <vector>

#include "estimation/model_fit.h"
#include "estimation/motion_trace.h"

namespace echoservo::estimation {

struct MotionModelSpec {
  int harmonics = 2;
  bool respiration = false;
  bool rate_drift = false;
};

// Throws std::invalid_argument naming the bad term and listing the catalog.
MotionModelSpec ParseMotionModel(const std::string& spec);
std::string FormatMotionModel(const MotionModelSpec& spec);
// The catalog: "harmonic", "respiration", "rate_drift".
std::vector<std::string> MotionEffectNames();
std::string MotionEffectSignature(const std::string& effect);
// The effects not yet in `spec` (harmonic always, up to 12 harmonics).
std::vector<std::string> MissingMotionEffects(const MotionModelSpec& spec);
MotionModelSpec WithMotionEffect(MotionModelSpec spec, const std::string& effect);

struct MotionFit {
  MotionModelSpec spec;
  std::vector<double> parameters;
  std::vector<ParameterEstimate> estimates;
  std::vector<double> prediction_mm;  // at every sample of the trace
  std::vector<double> phase_rad;      // cardiac phase at every sample, wrapped to [0, 2π)
  double rms_mm = 0.0;                // over the whole trace
  double mse_norm = 0.0;              // over the fitted subset, noise variances
  double seconds = 0.0;
};

// Fits `spec` to the samples `subset` (all when empty). `initial` (optional): starting
// parameters of the same spec. Throws std::invalid_argument for a trace shorter than
// two beats at 0.6 Hz.
MotionFit FitMotionModel(const MotionModelSpec& spec, const MotionTrace& trace, double noise_mm,
                         const std::vector<std::size_t>& subset = {},
                         const std::vector<double>* initial = nullptr);

// Mean-square residual (noise variances) of fixed `parameters` on `subset`.
double EvaluateMotionModel(const MotionModelSpec& spec, const std::vector<double>& parameters,
                           const MotionTrace& trace, double noise_mm,
                           const std::vector<std::size_t>& subset);

// Parameters of `to` started from a fit of `from` (shared values copied, new ones
// neutral; a new respiration term gets its rate from the residual's strongest slow
// sinusoid).
std::vector<double> StartMotionParameters(const MotionModelSpec& to, const MotionFit& from,
                                          const MotionTrace& trace);

}  // namespace echoservo::estimation
