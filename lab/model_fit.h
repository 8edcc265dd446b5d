// Fit of a catheter model (a model SPEC of catalog effects) to a lab dataset.
//
// One Ceres problem for all trials: the effects' physical parameters are shared by every
// trial (bounded by their physical ranges), each trial adds its nuisance parameters
// (tip-sensor offset, initial contact state). Residuals are the tip and force errors of
// the model run along the measured base (lab/model_prediction.h), divided by the
// dataset's noise levels, on every stride-th sample; derivatives by central differences
// (the deadzone is not smooth). Standard deviations come from ceres::Covariance scaled
// by the reduced χ². `Evaluate` keeps the physical parameters fixed and fits only the
// nuisance of each trial (for held-out trials). Units: mm, s, N.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "hw/effect_registry.h"
#include "lab/lab_dataset.h"
#include "lab/model_prediction.h"

namespace echoservo::lab {

struct ParameterEstimate {
  std::string name;  // "<effect>.<parameter>"
  std::string unit;
  double value = 0.0;
  double sd = 0.0;  // NaN when the covariance is rank deficient
};

struct ChannelStats {
  double tip_rms_mm = 0.0;
  double tip_mae_mm = 0.0;
  double tip_max_mm = 0.0;
  double force_rms_n = 0.0;
  std::size_t samples = 0;
};

struct TrialResult {
  std::string name;
  TrialNuisance nuisance;
  ChannelStats stats;
  Prediction prediction;  // full rate
};

struct FitResult {
  std::vector<std::string> effects;
  std::vector<double> parameters;
  std::vector<ParameterEstimate> estimates;
  std::vector<TrialResult> trials;  // in the order of the trial subset
  ChannelStats overall;
  // Mean-square residual of each channel over the fit samples, in units of the noise
  // variance (≈ 1 when the model explains everything but the noise).
  double tip_mse_norm = 0.0;
  double force_mse_norm = 0.0;
  int iterations = 0;
  double seconds = 0.0;
};

// A tabulated term among the physical parameters (a learned shape, lab/shape_learning.h):
// the n0·n1 consecutive parameters starting at the one named `first` ("<effect>.<name>")
// are its knot values, row-major (axis 0 slowest), over the hook inputs `inputs` at
// `knots` (hw/effect_file.h, "tables").
// Smoothness: the fit adds the residuals √(lambda·m)·Δ²v / scale for every second
// difference Δ²v along each axis, m being the number of fit samples of the trials fitted,
// so that lambda means the same on any subset (lab/smooth_shape.h's convention; scale: the
// channel's noise σ in the values' unit).
// Speed: the hook is linear in the knot values and, for a friction magnitude, a signed
// force or a tip-sensor offset along the trial's own signals, acts on each sample's
// prediction alone; the knot values' Jacobian is then d_i·φ_k(x_i), with d_i the
// prediction's derivative with respect to the hook at sample i (one central difference of
// all knot values at once, the hat functions summing to one) and φ_k the hat functions:
// 2 predictions per trial instead of 2 per knot. `local` says that this holds.
struct TabulatedBlock {
  std::string first;
  std::vector<std::string> inputs;         // 1 or 2 hook inputs (signals or geometry)
  std::vector<std::vector<double>> knots;  // one strictly increasing array per input
  double lambda = 0.0;
  double scale = 1.0;
  bool local = false;
  std::size_t size() const;
};

struct FitOptions {
  int max_iterations = 30;
  int threads = 2;
  // Called with a progress line (for fits longer than a second).
  std::function<void(const std::string&)> progress;
  const hw::EffectRegistry* registry = nullptr;  // null: built-in catalog
  std::vector<TabulatedBlock> tables;            // only for parameters the model has
};

// Fits `effects` to the trials in `subset` (all when empty). `initial` (optional) gives
// starting values of the physical parameters. Throws std::invalid_argument for unknown
// effects or an empty subset.
FitResult FitModel(const std::vector<std::string>& effects, const LabDataset& dataset,
                   const FitOptions& options, const std::vector<std::size_t>& subset = {},
                   const std::vector<double>* initial = nullptr);

// Evaluates fixed physical `parameters` on the trials in `subset`, fitting only each
// trial's nuisance parameters.
FitResult EvaluateModel(const std::vector<std::string>& effects,
                        const std::vector<double>& parameters, const LabDataset& dataset,
                        const FitOptions& options, const std::vector<std::size_t>& subset);

// The effect catalog a fit draws from: options.registry, or the built-in catalog.
const hw::EffectRegistry& FitCatalog(const FitOptions& options);

}  // namespace echoservo::lab
