// `lab diagnose`: which catalog effect is the model missing?
//
// For every catalog effect not in the model, SPEC+effect is refitted and scored on
// held-out trials (k-fold cross-validation by trial: physical parameters fitted on the
// other folds, only the nuisance refitted on the held-out trials), so an added
// parameter must predict trials it was not fitted to. Scores are in units of the noise
// variance: a channel's "excess" is its held-out mean-square residual minus 1 (what
// noise alone leaves). A candidate is significant when it removes at least
// `min_explained` of the excess of a channel whose excess is at least `min_excess`
// without making the other channel notably worse; candidates are ranked by the total
// held-out residual they remove. When none is significant the model is "adequate".
// The evidence is put in words from the residual breakdown (phase, speed, configuration).
#pragma once

#include <string>
#include <vector>

#include "lab/residual_breakdown.h"

namespace echoservo::lab {

struct DiagnoseOptions {
  FitOptions fit;
  int folds = 2;
  double min_excess = 0.5;              // channel excess (noise variances) worth explaining
  double min_explained = 0.3;           // fraction of that excess a candidate must remove
  int threads = 2;                      // candidates fitted in parallel
  std::vector<std::string> candidates;  // empty: every catalog effect not in the model
};

struct CrossValidation {
  double tip_mse = 0.0;  // held-out, in noise variances
  double force_mse = 0.0;
};

struct Candidate {
  std::string effect;
  FitResult fit;  // SPEC+effect on all trials
  CrossValidation cv;
  // Fraction of the model's held-out tip excess removed; NaN when the model leaves less
  // than `min_excess` in that channel (nothing to explain).
  double tip_explained = 0.0;
  double force_explained = 0.0;
  double score = 0.0;  // held-out residual removed, noise variances
  bool significant = false;
  std::string channel;  // "tip" or "force": where it explains most
  std::string evidence;
};

struct Diagnosis {
  std::vector<std::string> model;
  FitResult base;
  CrossValidation base_cv;
  Breakdown breakdown;                // of the model's residual
  std::vector<Candidate> candidates;  // best first
  bool adequate = false;
  std::string verdict;
};

Diagnosis Diagnose(const std::vector<std::string>& model, const LabDataset& dataset,
                   const DiagnoseOptions& options);

// The error ladder: starting from `model`, diagnose, add the best significant candidate,
// and repeat until the model is adequate or `max_rounds` effects were added. One step
// per model visited (the first is `model` itself), each with its diagnosis.
struct LadderStep {
  std::vector<std::string> model;
  Diagnosis diagnosis;
};
std::vector<LadderStep> ErrorLadder(const std::vector<std::string>& model,
                                    const LabDataset& dataset, const DiagnoseOptions& options,
                                    int max_rounds = 4);

// Held-out scores of `effects` (exposed for tests).
CrossValidation CrossValidate(const std::vector<std::string>& effects, const LabDataset& dataset,
                              const FitOptions& options, int folds,
                              const std::vector<double>* initial);

}  // namespace echoservo::lab
