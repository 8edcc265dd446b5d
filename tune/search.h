// The searches of a tuning study (tune/study.h): which parameter sets to try. A set is
// one value per axis (tune/study_spec.h ParameterAxis), in the axes' order, in each
// parameter's own unit (live/pipeline_parameters.h).
//   grid     — every combination of the axes' values (the first axis varies slowest);
//   random   — `count` sets drawn with a seeded generator (std::mt19937_64): an axis with
//              values (explicit or min..max in steps) uniformly among them, a continuous
//              axis uniformly in [min, max], integer axes rounded to the nearest integer,
//              boolean axes 0 or 1; duplicates dropped (and drawn again, a bounded number of
//              times: a small discrete space may hold fewer distinct sets than asked);
//   adaptive — NLopt's BOBYQA (Powell's bounded quadratic-model method, derivative-free) on
//              the axes scaled to [0, 1]: it proposes one set at a time, sequentially, from
//              the losses of those before; continuous (real) axes only. Deterministic: the
//              same losses give the same proposals (BOBYQA draws no random numbers).
// A loss is what the search minimises (the study's objective, negated when it is to be
// maximised). A set whose loss is not finite (its trials failed) gets a penalty instead:
// the worst finite loss seen so far (1e6 when none is finite yet): as bad as the worst set,
// so the model steers away from it, without an infinite value or a cliff breaking BOBYQA's
// quadratic model (a larger penalty made it converge beside the optimum in the tests).
// Errors: std::invalid_argument naming the axis and why (no values, empty range, an integer
// or boolean axis in an adaptive search, fewer than 1 evaluation).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "tune/study_spec.h"

namespace echoservo::tune {

using AxisValues = std::vector<double>;  // one value per axis, in axis order

// Every combination of the axes' values, first axis slowest. No axes: no set.
std::vector<AxisValues> GridProposals(const std::vector<ParameterAxis>& axes);

// `count` distinct sets (fewer when the space is smaller), uniform in each range.
std::vector<AxisValues> RandomProposals(const std::vector<ParameterAxis>& axes, int count,
                                        std::uint64_t seed);

// The penalty for a set whose loss is not finite, given the finite losses seen before it.
double FailedSetPenalty(const std::vector<double>& finite_losses);

struct AdaptiveOptions {
  int max_evaluations = 20;    // sets the optimiser may ask for, >= 1 (each one a set of trials)
  AxisValues start;            // the first set (clamped into the ranges); empty: the centre
  double initial_step = 0.25;  // BOBYQA's first trust-region radius, fraction of each range
  double resolution = 0.001;   // stop when BOBYQA's trust region is below this fraction of
                               // each range
  std::uint64_t seed = 1;      // NLopt's generator (BOBYQA itself draws none)
};

struct AdaptiveResult {
  AxisValues best;               // the set with the lowest loss
  double best_loss = 0.0;        // its loss (a penalty when every set failed)
  int evaluations = 0;           // calls of the objective
  std::string stop_reason;       // "evaluation budget spent", "converged (step < …)", …
  std::vector<AxisValues> sets;  // every set asked for, in order
  std::vector<double> losses;    // their losses (penalties where not finite)
};

// Minimises `loss` over the axes' ranges, calling it sequentially (one set at a time) at
// most max_evaluations times. `loss` may return NaN or ±inf for a failed set, and may throw
// to stop the search (the exception propagates).
AdaptiveResult AdaptiveSearch(const std::vector<ParameterAxis>& axes, const AdaptiveOptions& o,
                              const std::function<double(const AxisValues&)>& loss);

}  // namespace echoservo::tune
