// `lab compare|diagnose` on a target-motion trace: which effect is the motion model
// missing? The same procedure as the catheter lab (estimation/diagnosis.h) with the
// same machinery (estimation/candidate_ranking.h): the model and the model plus each
// missing catalog effect (estimation/motion_model.h) are scored by cross-validation —
// here over time blocks (`block_s` long, dealt into `folds` folds), since a trace is one
// recording — in units of the noise variance, and a candidate must remove a significant
// part of the held-out excess.
//
// Noise: the smaller of the robust second-difference scale of the trace
// (estimation/lab_dataset.h: EstimateNoise) and the residual σ of the richest model
// (the SPEC plus every catalog effect and 3 more harmonics). With an effect outside the
// catalog the noise is overestimated and the model may be called adequate.
// The residual breakdown groups samples by cardiac phase (8 bins) and by time (6
// segments), with each group's share of samples and of the squared residual.
#pragma once

#include <string>
#include <vector>

#include "estimation/candidate_ranking.h"
#include "estimation/motion_model.h"

namespace echoservo::estimation {

struct MotionGroup {
  std::string label;
  std::size_t samples = 0;
  double rms_mm = 0.0;
  double sample_share = 0.0;
  double error_share = 0.0;
};

struct MotionBreakdown {
  std::vector<MotionGroup> cardiac_phase;
  std::vector<MotionGroup> time;
};

MotionBreakdown ComputeMotionBreakdown(const MotionTrace& trace, const MotionFit& fit);

// The noise σ (mm) the lab uses for `spec` on `trace`.
double MotionLabNoise(const MotionModelSpec& spec, const MotionTrace& trace);

struct MotionDiagnoseOptions {
  int folds = 2;
  double block_s = 2.0;
  SignificanceRule rule;
  int threads = 2;
};

struct MotionCandidate {
  std::string effect;
  MotionFit fit;
  double cv_mse = 0.0;
  double explained = 0.0;  // NaN when the model leaves no excess
  double score = 0.0;
  bool significant = false;
  std::string evidence;
};

struct MotionDiagnosis {
  MotionModelSpec model;
  double noise_mm = 0.0;
  MotionFit base;
  double base_cv_mse = 0.0;
  MotionBreakdown breakdown;
  std::vector<MotionCandidate> candidates;  // best first
  bool adequate = false;
  std::string verdict;
};

// Held-out mean square (noise variances) of `spec` over time-block folds.
double CrossValidateMotion(const MotionModelSpec& spec, const MotionTrace& trace, double noise_mm,
                           const MotionDiagnoseOptions& options,
                           const std::vector<double>* initial);

MotionDiagnosis DiagnoseMotion(const MotionModelSpec& spec, const MotionTrace& trace,
                               const MotionDiagnoseOptions& options = {});

}  // namespace echoservo::estimation
