// `lab compare|diagnose` on a target-motion trace: which effect is the motion model
// missing? The catheter lab's procedure (lab/diagnosis.h) and machinery
// (lab/candidate_ranking.h): the model and the model plus each missing catalog effect
// (lab/motion_model.h) are scored by cross-validation over time blocks, in units of the
// noise variance; a candidate must remove a significant part of the held-out excess.
//
// In: a trace (t in s, position in mm) and a model SPEC. Out: candidates best first, the
// noise σ (mm) used, and a residual breakdown by cardiac phase and by time segment. An
// effect outside the catalog inflates the noise estimate and may let the model pass.
// Details: docs/model_lab.md#motion-diagnosis-labmotion_diagnosish
#pragma once

#include <string>
#include <vector>

#include "lab/candidate_ranking.h"
#include "lab/motion_model.h"

namespace echoservo::lab {

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

MotionBreakdown ComputeMotionBreakdown(const estimation::MotionTrace& trace, const MotionFit& fit);

// The noise σ (mm) the lab uses for `spec` on `trace`.
double MotionLabNoise(const MotionModelSpec& spec, const estimation::MotionTrace& trace);

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
double CrossValidateMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                           double noise_mm, const MotionDiagnoseOptions& options,
                           const std::vector<double>* initial);

MotionDiagnosis DiagnoseMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                               const MotionDiagnoseOptions& options = {});

}  // namespace echoservo::lab
