// The paired statistics of the study report (tune/study_report.h): a parameter set against
// the default settings on the same recordings, through the per-recording differences
// d_r = objective(set, r) − objective(default, r) (the objective's unit).
//
// Mean difference: the plain mean of d. Confidence interval: percentile bootstrap over
// recordings (resample the n differences with replacement, take the mean, repeat B times;
// the interval is the (1−C)/2 and (1+C)/2 quantiles of those means), seeded. p-value:
// two-sided sign-flip permutation test of "no difference" (under it each d_r is as likely
// +|d_r| as −|d_r|): the share of sign patterns whose |Σ±d_r| is at least the observed
// |Σd_r|; exact over all 2^n patterns for n ≤ kMaxExactSignFlip, else (1 + hits)/(1 + M)
// over M seeded random patterns. With n < kMinPairedRecordings there is no interval or
// p-value (NaN): resampling two numbers says nothing about the spread.
// Errors: std::invalid_argument for bad sample counts or confidence.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

namespace echoservo::tune {

inline constexpr std::size_t kMinPairedRecordings = 3;
inline constexpr std::size_t kMaxExactSignFlip = 16;

struct PairedComparison {
  std::size_t n = 0;  // recordings where both trials finished
  double mean_difference = std::numeric_limits<double>::quiet_NaN();
  double ci_low = std::numeric_limits<double>::quiet_NaN();
  double ci_high = std::numeric_limits<double>::quiet_NaN();
  double p_value = std::numeric_limits<double>::quiet_NaN();
  bool exact = true;        // p from every sign pattern (else Monte Carlo)
  bool meaningful = false;  // n >= kMinPairedRecordings: interval and p computed
};

// Two-sided sign-flip p-value of `d` (any n >= 1); `monte_carlo_samples` patterns when n >
// kMaxExactSignFlip. `exact` (may be null) says which.
double SignFlipPValue(const std::vector<double>& d, int monte_carlo_samples, std::uint64_t seed,
                      bool* exact = nullptr);

// Percentile bootstrap interval of the mean of `d` (n >= 1), `samples` in [100, 1000000],
// `confidence` in (0, 1).
std::pair<double, double> BootstrapMeanCi(const std::vector<double>& d, int samples,
                                          double confidence, std::uint64_t seed);

// All of the above (interval and p only where n >= kMinPairedRecordings).
PairedComparison ComparePaired(const std::vector<double>& d, int bootstrap_samples,
                               double confidence, std::uint64_t seed);

}  // namespace echoservo::tune
