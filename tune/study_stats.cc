#include "tune/study_stats.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>

namespace echoservo::tune {
namespace {

double StudyStatsMean(const std::vector<double>& d) {
  double s = 0.0;
  for (double v : d) s += v;
  return s / static_cast<double>(d.size());
}

// Linear interpolation between order statistics of the sorted `v` at quantile q.
double StudyStatsQuantile(const std::vector<double>& v, double q) {
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  const double f = pos - static_cast<double>(lo);
  return v[lo] + f * (v[hi] - v[lo]);
}

void StudyStatsCheck(const std::vector<double>& d, const char* where) {
  if (d.empty()) throw std::invalid_argument(std::string(where) + ": no differences");
  for (double v : d) {
    if (!std::isfinite(v))
      throw std::invalid_argument(std::string(where) + ": a difference is not finite");
  }
}

}  // namespace

double SignFlipPValue(const std::vector<double>& d, int monte_carlo_samples, std::uint64_t seed,
                      bool* exact) {
  StudyStatsCheck(d, "SignFlipPValue");
  double observed = 0.0, scale = 0.0;
  for (double v : d) observed += v, scale += std::abs(v);
  observed = std::abs(observed);
  // Sums of the same terms in another order differ by rounding only: count those as ties.
  const double tol = 1e-9 * std::max(scale, 1e-300);
  const std::size_t n = d.size();
  if (n <= kMaxExactSignFlip) {
    if (exact != nullptr) *exact = true;
    // Gray-code walk: each step flips one sign, so each pattern's sum costs O(1).
    const std::uint32_t patterns = 1u << n;
    std::vector<int> sign(n, 1);
    double sum = 0.0;
    for (double v : d) sum += v;
    std::uint64_t hits = 0;
    for (std::uint32_t i = 0; i < patterns; ++i) {
      if (i > 0) {
        const int j = __builtin_ctz(i);
        sum -= 2.0 * sign[static_cast<std::size_t>(j)] * d[static_cast<std::size_t>(j)];
        sign[static_cast<std::size_t>(j)] = -sign[static_cast<std::size_t>(j)];
      }
      if (std::abs(sum) >= observed - tol) ++hits;
    }
    return static_cast<double>(hits) / static_cast<double>(patterns);
  }
  if (exact != nullptr) *exact = false;
  if (monte_carlo_samples < 100)
    throw std::invalid_argument("SignFlipPValue: fewer than 100 Monte Carlo patterns");
  std::mt19937_64 rng(seed);
  std::uint64_t hits = 0;
  for (int k = 0; k < monte_carlo_samples; ++k) {
    double sum = 0.0;
    std::uint64_t bits = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (i % 64 == 0) bits = rng();
      sum += (bits & 1u) != 0 ? d[i] : -d[i];
      bits >>= 1;
    }
    if (std::abs(sum) >= observed - tol) ++hits;
  }
  return (1.0 + static_cast<double>(hits)) / (1.0 + static_cast<double>(monte_carlo_samples));
}

std::pair<double, double> BootstrapMeanCi(const std::vector<double>& d, int samples,
                                          double confidence, std::uint64_t seed) {
  StudyStatsCheck(d, "BootstrapMeanCi");
  if (samples < 100 || samples > 1000000)
    throw std::invalid_argument("BootstrapMeanCi: samples " + std::to_string(samples) +
                                " outside [100, 1000000]");
  if (!(confidence > 0.0 && confidence < 1.0))
    throw std::invalid_argument("BootstrapMeanCi: confidence outside (0, 1)");
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, d.size() - 1);
  std::vector<double> means(static_cast<std::size_t>(samples));
  for (double& m : means) {
    double s = 0.0;
    for (std::size_t i = 0; i < d.size(); ++i) s += d[pick(rng)];
    m = s / static_cast<double>(d.size());
  }
  std::sort(means.begin(), means.end());
  const double alpha = 1.0 - confidence;
  return {StudyStatsQuantile(means, alpha / 2.0), StudyStatsQuantile(means, 1.0 - alpha / 2.0)};
}

PairedComparison ComparePaired(const std::vector<double>& d, int bootstrap_samples,
                               double confidence, std::uint64_t seed) {
  PairedComparison c;
  c.n = d.size();
  if (d.empty()) return c;
  StudyStatsCheck(d, "ComparePaired");
  c.mean_difference = StudyStatsMean(d);
  if (c.n < kMinPairedRecordings) return c;
  c.meaningful = true;
  std::tie(c.ci_low, c.ci_high) = BootstrapMeanCi(d, bootstrap_samples, confidence, seed);
  // A separate stream for the Monte Carlo test, so the interval does not depend on n.
  c.p_value =
      SignFlipPValue(d, std::max(bootstrap_samples, 10000), seed ^ 0x9e3779b97f4a7c15ULL, &c.exact);
  assert(c.p_value > 0.0 && c.p_value <= 1.0);
  return c;
}

}  // namespace echoservo::tune
