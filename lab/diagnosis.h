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
// Verdicts: "missing_effect" when a candidate is significant; otherwise "unexplained" when a
// channel keeps a significant held-out excess (≥ min_excess noise variances) or a
// variable of `where` (lab/catheter_where.h) explains ≥ min_structure noise variances of
// it on held-out trials — then a new effect is proposed from the data
// (lab/effect_discovery.h); otherwise "adequate". The noise floor is the dataset's
// (lab/lab_dataset.h: from the signals' second differences), not the model's.
// The error ladder also tries replacing an effect it added earlier by another.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "hw/effect_file.h"
#include "lab/learned_term.h"
#include "lab/residual_breakdown.h"
#include "lab/residual_structure.h"

namespace echoservo::lab {

struct DiagnoseOptions {
  FitOptions fit;
  int folds = 2;
  double min_excess = 0.5;              // channel excess (noise variances) worth explaining
  double min_explained = 0.3;           // fraction of that excess a candidate must remove
  int threads = 2;                      // candidates fitted in parallel
  std::vector<std::string> candidates;  // empty: every catalog effect not in the model
  // Effects of the model that may be replaced by a candidate (the ladder's own additions),
  // each by the `swap_candidates` best additions.
  std::vector<std::string> swappable;
  int swap_candidates = 2;
  // Held-out noise variances a variable of `where` must explain to count as structure.
  double min_structure = 0.25;
  // Propose an effect when the verdict is "unexplained" (lab/effect_discovery.h).
  bool discover = true;
  int max_terms = 2;                  // terms of a proposal
  int variables_per_channel = 3;      // top `where` variables screened per channel
  int refit = 3;                      // screened terms fitted through the full model, at most
  std::filesystem::path propose_dir;  // where the proposal's effect file goes ("": not written)
  // A candidate (or proposal) closes the gap when every channel's held-out RMS is at most
  // this multiple of the noise floor; only then is it named as *the* missing effect.
  double close_ratio = 1.5;
  // Learn the missing term as a shape and distil it into a formula (lab/shape_learning.h)
  // when neither the catalog nor the discovery library closes the gap.
  bool learn = true;
  // A formula is proposed instead of the learnt shape when its held-out RMS in the shape's
  // channel is within this multiple of the shape's.
  double formula_tolerance = 1.2;
  // The variables (and pairs "slow*fast") a shape is learnt along; empty: the top `where`
  // variables and the trial-level pairs. Checked by CheckLearnVariables.
  std::vector<std::string> learn_along;
};

struct CrossValidation {
  double tip_mse = 0.0;  // held-out, in noise variances
  double force_mse = 0.0;
  // With CrossValidate(..., keep_predictions = true): each trial's held-out prediction.
  std::vector<Prediction> held_out;
};

struct Candidate {
  std::string effect;
  std::string replaces;  // a model effect this candidate replaces ("" when it is added)
  FitResult fit;         // SPEC+effect on all trials
  CrossValidation cv;
  // Fraction of the model's held-out tip excess removed; NaN when the model leaves less
  // than `min_excess` in that channel (nothing to explain).
  double tip_explained = 0.0;
  double force_explained = 0.0;
  double score = 0.0;  // held-out residual removed, noise variances
  bool significant = false;
  // Every channel's held-out RMS within DiagnoseOptions::close_ratio of the noise floor.
  bool closes_gap = false;
  std::string channel;  // "tip" or "force": where it explains most
  std::string evidence;
};

// A new effect learned from the data (lab/effect_discovery.h).
struct Proposal {
  hw::EffectFileSpec effect;         // fitted values as defaults
  std::vector<std::string> effects;  // the model plus the proposed effect
  std::string spec;                  // usable with --model (the file as @path)
  std::string file;                  // where the effect file was written ("" if not)
  std::string equation;              // in words and units
  std::vector<std::string> terms;    // library ids of the chosen terms
  FitResult fit;
  CrossValidation cv;
  std::size_t cv_trials = 0;  // trials the held-out figures are on
  // Terms learnt in earlier rounds (a second effect learnt on top of the first), in the
  // model before `effect`; written beside it.
  std::vector<hw::EffectFileSpec> earlier;
  double rms_mm = 0.0;       // held-out tip RMS (mm): sqrt(cv tip mse)·noise
  double force_rms_n = 0.0;  // held-out force RMS (N)
};

struct Diagnosis {
  std::vector<std::string> model;
  FitResult base;
  CrossValidation base_cv;
  Breakdown breakdown;                // of the model's residual
  std::vector<Candidate> candidates;  // best first
  double tip_excess = 0.0;            // held-out mean square − 1, noise variances
  double force_excess = 0.0;
  std::vector<WhereEntry> where;  // ranked per channel
  bool adequate = false;
  std::string verdict;               // "adequate" | "missing_effect" | "unexplained"
  std::string summary;               // the verdict in a sentence, with its figures
  std::optional<Proposal> proposal;  // when unexplained and a proposal was found
  // A significant candidate that does not close the gap (not even with the best candidate
  // of the other channel): it "partly explains" `partial_fraction` of its channel's excess,
  // the verdict is unexplained, and what remains is learnt on top of it.
  std::string partial;
  double partial_fraction = 0.0;
  // With a missing effect that closes the gap only together with another candidate: that one.
  std::string closes_with;
  ShapeLearning learning;  // what was learnt beyond the catalog and the library
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

// Starting values for `effects`: each effect's default, or the value `fit` found where it
// has the same parameter.
std::vector<double> StartingValues(const FitResult& fit, const std::vector<std::string>& effects,
                                   const LabDataset& dataset, const FitOptions& options);

// Held-out scores of `effects` (exposed for tests).
CrossValidation CrossValidate(const std::vector<std::string>& effects, const LabDataset& dataset,
                              const FitOptions& options, int folds,
                              const std::vector<double>* initial, bool keep_predictions = false);

}  // namespace echoservo::lab
