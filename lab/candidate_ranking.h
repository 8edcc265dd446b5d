// The model lab's machinery for choosing what a model misses, shared by the catheter lab
// (lab/diagnosis.h) and the target-motion lab (lab/motion_diagnosis.h).
//
// Scores are held-out mean-square residuals per channel in units of the noise variance
// (1 = only noise left). A channel's excess is its score minus 1. A candidate explains
// (base − candidate)/excess of a channel whose excess is at least `min_excess`; it is
// significant when that is at least `min_explained` in some channel without making any
// other channel notably worse (by more than max(10 % of its excess, 0.5)). Candidates
// rank significant first, then by the total held-out residual they remove.
// Cross-validation: units (trials, time blocks) are dealt into folds by index modulo k;
// each fold is fitted on the other folds and scored on itself; scores are averaged with
// the folds' weights (residual counts).
#pragma once

#include <algorithm>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace echoservo::lab {

struct SignificanceRule {
  double min_excess = 0.5;
  double min_explained = 0.3;
};

struct Judgement {
  std::vector<double> explained;  // per channel; NaN where the base leaves < min_excess
  double score = 0.0;             // held-out residual removed, summed over channels
  bool significant = false;
  std::size_t channel = 0;  // where it explains most
};

// `base` and `candidate`: held-out scores per channel (same length, ≥ 1).
Judgement JudgeCandidate(const std::vector<double>& base, const std::vector<double>& candidate,
                         const SignificanceRule& rule);

// Significant first, then by score (stable). T has `significant` and `score`.
template <class T>
void RankCandidates(std::vector<T>& candidates) {
  std::stable_sort(candidates.begin(), candidates.end(), [](const T& a, const T& b) {
    if (a.significant != b.significant) return a.significant;
    return a.score > b.score;
  });
}

// Runs job(0..count−1) on `threads` workers pulling from a shared counter.
void ForEachInParallel(std::size_t count, int threads, const std::function<void(std::size_t)>& job);

struct FoldScore {
  std::vector<double> mse;  // per channel, noise variances
  double weight = 0.0;      // residual count
};
using FoldFunction = std::function<FoldScore(const std::vector<std::size_t>& train,
                                             const std::vector<std::size_t>& test)>;
// Weighted mean of the folds' scores; requires units ≥ 2 and folds ≥ 2. Units are dealt
// into folds by index modulo k, or by `assignment` (a fold in 0..k−1 per unit) when given.
std::vector<double> CrossValidateFolds(std::size_t units, int folds, const FoldFunction& fold,
                                       const std::vector<int>* assignment = nullptr);

// Folds of `units` units dealt in a fixed pseudo-random order (the same every run), so that
// a pattern in the units' order (trials alternating between two trajectories) cannot
// line up with the folds: fold sizes differ by at most one.
std::vector<int> ShuffledFolds(std::size_t units, int folds);

// "42%" (never "-0%").
std::string PercentText(double fraction);
// printf "%.*f".
std::string FixedText(double value, int decimals);

}  // namespace echoservo::lab
