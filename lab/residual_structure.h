// Where a model fails, along any variable: how much of a channel's residual a smooth
// function of one variable (or of a pair) predicts on data it was not fitted to.
//
// The residuals are in units of the channel's noise σ (so a model that explains
// everything leaves a mean square of about 1). The smooth function is a binned mean:
// the variable is cut into `bins` bins at its quantiles (ties kept together), each bin's
// mean residual is learnt on the training folds (shrunk towards 0 by n/(n + shrink) so
// that a bin with few samples predicts little), and the held-out folds are predicted by
// their bin's mean. The gain is the held-out mean-square residual removed, in noise
// variances: noise alone and a variable the residual does not depend on leave a gain ≤ 0
// (the function learnt on other folds only adds its own error), a residual that depends
// on the variable a positive one. Folds are given per sample (trials for catheter data,
// time blocks for motion traces), so the function must carry over to other trials/blocks.
// A pair of variables (cardiac phase × slow time) is one variable whose bin is the pair of
// bins: pass the combined bin index with ExplainedByBins.
// Units: residuals in noise σ, gains in noise variances, fractions of the excess in [0, 1].
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace echoservo::lab {

struct StructureOptions {
  int bins = 12;         // quantile bins per variable
  double shrink = 20.0;  // samples: a bin's mean is shrunk by n/(n + shrink)
};

// Bin index (0..bins−1) of every sample of `x` at the quantiles of `x` (equal values share
// a bin; fewer bins when `x` has fewer distinct values).
std::vector<int> QuantileBins(const std::vector<double>& x, int bins);

// Held-out mean-square residual removed (noise variances) by the binned mean over `bin`,
// with folds `fold` (values 0..folds−1; each fold predicted from the others). `r`, `bin`
// and `fold` have equal length; samples with a negative fold are skipped.
double ExplainedByBins(const std::vector<double>& r, const std::vector<int>& bin,
                       const std::vector<int>& fold, const StructureOptions& options = {});

// The same for a continuous variable (QuantileBins(x, options.bins)).
double ExplainedByVariable(const std::vector<double>& r, const std::vector<double>& x,
                           const std::vector<int>& fold, const StructureOptions& options = {});

// One row of `where`: how much of a channel's held-out excess a variable explains.
struct WhereEntry {
  std::string channel;              // "tip" | "force" | "position"
  std::string variable;             // e.g. "base_mm", "time_s", "cardiac_phase_x_time"
  double gain = 0.0;                // held-out mean square removed, noise variances (may be < 0)
  double explained_fraction = 0.0;  // gain / channel excess, clipped to [0, 1]
};

// Sorts entries by channel (in first-seen order) and, within a channel, by gain (largest
// first).
void RankWhere(std::vector<WhereEntry>& entries);

}  // namespace echoservo::lab
