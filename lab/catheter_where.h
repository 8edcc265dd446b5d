// Where a catheter model fails: its held-out residuals laid out per sample with every
// variable a misfit can live along, and how much of each channel's excess a smooth
// function of each variable explains (lab/residual_structure.h).
//
// The residuals are those of the cross-validation (lab/diagnosis.h): each trial predicted
// by parameters fitted on the other folds, (model − measurement)/noise σ, on the fit
// samples. Variables, per sample: base_mm, tip_mm (measured), tip_model_mm (the model's tip
// reading), velocity_mm_s, acceleration_mm_s2, force_n (measured), force_model_n (the
// model's force), time_s (since the trial's start); per trial: bend_deg (total bend angle),
// gap_mm (sheath ID − guidewire OD), tip_load_n. A channel's own measurement is never a
// variable of its residual (the residual is model − that measurement, so it always
// correlates and says nothing): tip_mm is left out for the tip, force_n for the force; the
// model's prediction of the channel stands in. Pairs "slow*fast" of a trial-level variable
// (bend_deg, gap_mm, tip_load_n) and a sample-level one (base_mm, velocity_mm_s,
// acceleration_mm_s2, time_s) are binned jointly (4 × 6 bins, with the direction) and
// ranked with the single variables when they explain clearly more than either alone
// (0.05 noise variances and 10 % of the excess): an interaction; one pair, the best, per
// trial-level variable and channel. Friction acts
// against the motion, so a friction misfit changes sign with the direction of motion and
// averages out along any variable taken alone: every variable is therefore binned jointly
// with the direction of motion (moving in −, at rest below 1 mm/s, moving in +). Folds
// are the cross-validation's (ShuffledFolds over trials); a dataset of one trial uses 0.5 s
// time blocks instead. Units: mm, s, N; residuals in noise σ, gains in noise variances.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "lab/lab_dataset.h"
#include "lab/model_prediction.h"
#include "lab/residual_structure.h"

namespace echoservo::lab {

struct ResidualTable {
  std::vector<std::size_t> trial;  // dataset trial of each sample
  std::vector<std::size_t> index;  // sample within the trial
  std::vector<int> fold;
  std::vector<int> direction;  // −1, 0 (rest), +1
  std::vector<double> tip;     // held-out residuals, tip noise σ
  std::vector<double> force;   // held-out residuals, force noise σ
  std::vector<std::string> names;
  std::vector<std::vector<double>> variables;                        // names[v] at every sample
  const std::vector<double>& Variable(std::string_view name) const;  // asserts it exists
  std::size_t size() const { return tip.size(); }
};

// The variables, in the order of ResidualTable::names.
const std::vector<std::string>& WhereVariables();
// Whether `variable` is `channel`'s own measurement (never a variable of its residual).
bool CircularFor(std::string_view channel, std::string_view variable);
// Whether a `where` variable is a pair "slow*fast", and its two variables.
bool IsPair(std::string_view variable);
std::pair<std::string, std::string> SplitPair(std::string_view variable);

// `held_out` holds one prediction per trial of `dataset` (full rate).
ResidualTable BuildResidualTable(const LabDataset& dataset, const std::vector<Prediction>& held_out,
                                 int folds);

// Per channel ("tip", "force") and variable: the held-out gain of a binned function of
// (variable, direction) and its fraction of the channel's excess (held-out mean square in
// noise variances minus 1; a fraction is 0 when the excess is below 0.05). Ranked.
std::vector<WhereEntry> LocateResidual(const ResidualTable& table, double tip_excess,
                                       double force_excess, const StructureOptions& options = {});

// Bin of every sample for `variable` (or a pair) jointly with the direction of motion
// (exposed for the discovery's screening and the report's plots).
std::vector<int> DirectionalBins(const ResidualTable& table, std::string_view variable, int bins);

}  // namespace echoservo::lab
