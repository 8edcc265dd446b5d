// Target-motion models for the model lab: what `lab compare|diagnose` fit to a motion
// trace (estimation/motion_trace.h), the counterpart of the catheter's effect SPECs.
//
// SPEC: "heartbeat:N" (offset + N harmonics of a constant heart rate) plus "+effect" terms
// of the motion catalog: respiration, rate_drift, harmonic, and "+@path/term.json" terms
// defined in effect files (lab/motion_terms.h; their position_mm is added to the position,
// their phase_rad to the heartbeat's phase, their parameters fitted with the rest; the path
// may not contain '+'). Fitted by Ceres,
// residuals in units of the noise σ, started from a rate search (estimation/harmonic_fit.h);
// automatic derivatives, central differences when a file term is present; standard
// deviations from ceres::Covariance. Units: s, Hz, mm, rad.
// Errors: std::invalid_argument for an unknown SPEC term (naming it, listing the catalog),
// for a bad term file (naming the file, key and why) and for a trace shorter than two
// beats at 0.6 Hz.
// Details: docs/model_lab.md#motion-models-labmotion_modelh
#pragma once

#include <string>
#include <vector>

#include "estimation/motion_trace.h"
#include "lab/model_fit.h"
#include "lab/motion_terms.h"

namespace echoservo::lab {

struct MotionModelSpec {
  int harmonics = 2;
  bool respiration = false;
  bool rate_drift = false;
  std::vector<MotionTerm> terms;  // "+@file" terms and discovery's library terms, in order
};

// Throws std::invalid_argument naming the bad term and listing the catalog; "+@path" reads
// the term file (errors name the file).
MotionModelSpec ParseMotionModel(const std::string& spec);
// "heartbeat:N[+respiration][+rate_drift][+@path…][+library_term…]".
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
  std::vector<ParameterEstimate> estimates;  // term parameters as "<term>.<parameter>"
  std::vector<double> prediction_mm;         // at every sample of the trace
  std::vector<double> phase_rad;             // cardiac phase at every sample, wrapped to [0, 2π)
  std::vector<double> heartbeat_mm;  // the harmonics' sum (no offset) at every sample's phase
  double rms_mm = 0.0;               // over the whole trace
  double mse_norm = 0.0;             // over the fitted subset, noise variances
  double seconds = 0.0;
};

// Fits `spec` to the samples `subset` (all when empty). `initial` (optional): starting
// parameters of the same spec. Throws std::invalid_argument for a trace shorter than
// two beats at 0.6 Hz.
MotionFit FitMotionModel(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                         double noise_mm, const std::vector<std::size_t>& subset = {},
                         const std::vector<double>* initial = nullptr);

// Mean-square residual (noise variances) of fixed `parameters` on `subset`.
double EvaluateMotionModel(const MotionModelSpec& spec, const std::vector<double>& parameters,
                           const estimation::MotionTrace& trace, double noise_mm,
                           const std::vector<std::size_t>& subset);

// Parameters of `to` started from a fit of `from` (shared values copied, new ones
// neutral or at the term file's start values; a new respiration term gets its rate from
// the residual's strongest slow sinusoid).
std::vector<double> StartMotionParameters(const MotionModelSpec& to, const MotionFit& from,
                                          const estimation::MotionTrace& trace);

}  // namespace echoservo::lab
