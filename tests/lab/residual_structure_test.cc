// `where`'s statistics (lab/residual_structure.h) on synthetic residuals whose structure is
// known exactly: quantile bins, the held-out gain of a binned mean, and the ranking.
//
// The expected gains follow from the definition. A residual r = s(x) + ε with ε ~ N(0, 1)
// independent of everything: a bin mean m learnt on other folds removes, per sample,
// E[r² − (r − m)²] = E[2·s·m − m²]. For pure noise (s = 0) that is −E[m²] < 0 (the learnt
// function only adds its own error, ≈ −1/n for n samples per bin and fold); for s = sin(x)
// with x uniform over a period it is Var(sin) = 1/2, less what 12 bins cannot follow
// (the variance of sin within a bin of width π/6, ≈ (π/6)²/12 · 1/2 ≈ 0.011) and the
// estimation error (≈ 1/n); the binned mean's fluctuation over 20 000 samples is
// ≈ 2·sqrt(Var(ε)·Var(s)/N) ≈ 0.01.
#include "lab/residual_structure.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <set>
#include <vector>

namespace echoservo::lab::residual_structure_test {
namespace {

constexpr std::size_t kSamples = 20000;

// Two folds in alternating blocks of 100 samples (as trials would be).
std::vector<int> TwoFolds(std::size_t n) {
  std::vector<int> fold(n);
  for (std::size_t i = 0; i < n; ++i) fold[i] = static_cast<int>((i / 100) % 2);
  return fold;
}

std::vector<double> Uniform(std::mt19937_64& rng, std::size_t n, double lo, double hi) {
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<double> x(n);
  for (double& v : x) v = u(rng);
  return x;
}

std::vector<double> Gaussian(std::mt19937_64& rng, std::size_t n) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> x(n);
  for (double& v : x) v = g(rng);
  return x;
}

// ---------------------------------------------------------------------- QuantileBins

TEST(QuantileBins, DistinctValuesGiveEqualCountsInOrder) {
  std::mt19937_64 rng(3);
  std::vector<double> x(120);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = static_cast<double>(i) * 0.5;
  std::shuffle(x.begin(), x.end(), rng);
  const std::vector<int> bin = QuantileBins(x, 12);
  ASSERT_EQ(bin.size(), x.size());
  std::vector<int> count(12, 0);
  for (int b : bin) {
    ASSERT_GE(b, 0);
    ASSERT_LT(b, 12);
    ++count[static_cast<std::size_t>(b)];
  }
  for (int c : count) EXPECT_EQ(c, 10);  // 120 samples / 12 bins
  // Bins follow the values: a larger value never sits in a lower bin.
  for (std::size_t i = 0; i < x.size(); ++i) {
    for (std::size_t j = 0; j < x.size(); ++j) {
      if (x[i] < x[j]) {
        EXPECT_LE(bin[i], bin[j]) << x[i] << " vs " << x[j];
      }
    }
  }
}

TEST(QuantileBins, TiesShareABin) {
  // 60 zeros (half the samples) then 60 distinct values: the zeros cannot be split, so
  // they fill one bin and the rest share the remaining bins.
  std::vector<double> x(60, 0.0);
  for (int i = 1; i <= 60; ++i) x.push_back(i);
  std::mt19937_64 rng(5);
  std::shuffle(x.begin(), x.end(), rng);
  const std::vector<int> bin = QuantileBins(x, 6);
  std::set<int> zero_bins;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (x[i] == 0.0) zero_bins.insert(bin[i]);
  }
  ASSERT_EQ(zero_bins.size(), 1u);
  EXPECT_EQ(*zero_bins.begin(), 0);
  for (std::size_t i = 0; i < x.size(); ++i) {
    for (std::size_t j = 0; j < x.size(); ++j) {
      if (x[i] == x[j]) {
        EXPECT_EQ(bin[i], bin[j]);
      }
      if (x[i] < x[j]) {
        EXPECT_LE(bin[i], bin[j]);
      }
    }
  }
  EXPECT_GT(*std::max_element(bin.begin(), bin.end()), 1);  // the distinct values are split
}

TEST(QuantileBins, FewerDistinctValuesGiveFewerBins) {
  // Three values (a per-trial variable such as the gap): three bins, not twelve.
  std::vector<double> x;
  for (int i = 0; i < 90; ++i) x.push_back(0.25 * (i % 3));
  const std::vector<int> bin = QuantileBins(x, 12);
  const std::set<int> used(bin.begin(), bin.end());
  EXPECT_EQ(used, (std::set<int>{0, 1, 2}));
  for (std::size_t i = 0; i < x.size(); ++i) EXPECT_EQ(bin[i], static_cast<int>(i % 3));
  // One value: one bin; one bin asked for or no samples: all in bin 0.
  const std::vector<int> constant = QuantileBins(std::vector<double>(50, 4.0), 12);
  EXPECT_EQ(std::set<int>(constant.begin(), constant.end()), std::set<int>{0});
  const std::vector<int> one = QuantileBins(x, 1);
  EXPECT_EQ(std::set<int>(one.begin(), one.end()), std::set<int>{0});
  EXPECT_TRUE(QuantileBins({}, 12).empty());
}

// ---------------------------------------------------------------------- ExplainedByBins

TEST(ExplainedByBins, NoiseAlongAnUnrelatedVariableExplainsNothing) {
  const std::vector<int> fold = TwoFolds(kSamples);
  double sum = 0.0;
  const int seeds = 10;
  for (int seed = 1; seed <= seeds; ++seed) {
    std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
    const std::vector<double> r = Gaussian(rng, kSamples);
    const std::vector<double> x = Uniform(rng, kSamples, -5.0, 5.0);
    const double gain = ExplainedByVariable(r, x, fold);
    EXPECT_LE(gain, 0.02) << "seed " << seed;
    sum += gain;
  }
  // Expected −E[m²] ≈ −1/(n + shrink) with n ≈ 833 per bin and fold (≈ −0.0012), the
  // mean of ten seeds fluctuating by ≈ 0.0002: below 0. A function scored on the data it
  // was learnt from would give +E[m²] instead.
  EXPECT_LE(sum / seeds, 0.0);
}

TEST(ExplainedByBins, SineOfTheVariableExplainsItsVariance) {
  std::mt19937_64 rng(11);
  const std::vector<double> x = Uniform(rng, kSamples, 0.0, 2.0 * std::numbers::pi);
  const std::vector<double> noise = Gaussian(rng, kSamples);
  std::vector<double> r(kSamples);
  for (std::size_t i = 0; i < kSamples; ++i) r[i] = 1.0 * std::sin(x[i]) + noise[i];
  const std::vector<int> fold = TwoFolds(kSamples);
  // Var(sin) = 0.5, less ≈ 0.011 for 12 bins and ≈ 0.001 of estimation error; ±0.01
  // fluctuation (header).
  const double gain = ExplainedByVariable(r, x, fold);
  EXPECT_NEAR(gain, 0.5, 0.05);
  // The same residual along an unrelated variable: nothing.
  const std::vector<double> y = Uniform(rng, kSamples, 0.0, 1.0);
  EXPECT_LE(ExplainedByVariable(r, y, fold), 0.02);
  // Fewer bins follow the sine less closely (within-bin variance grows with the width).
  StructureOptions coarse;
  coarse.bins = 3;
  EXPECT_LT(ExplainedByVariable(r, x, fold, coarse), gain - 0.05);
}

TEST(ExplainedByBins, EachFoldIsPredictedOnlyFromTheOthers) {
  // The residual is +1 on fold 0 and −1 on fold 1 in every bin: learnt in-sample it would
  // be explained completely (gain 1); learnt on the other fold, each bin predicts the
  // opposite sign, shrunk by s = n/(n + shrink), so the gain is 1 − (1 + s)² < 0.
  const std::size_t n = 1200;
  std::vector<double> r(n);
  std::vector<int> bin(n);
  std::vector<int> fold(n);
  for (std::size_t i = 0; i < n; ++i) {
    fold[i] = static_cast<int>(i % 2);
    r[i] = fold[i] == 0 ? 1.0 : -1.0;
    bin[i] = static_cast<int>(i / 100);  // 12 bins of 100 samples, 50 per fold
  }
  const StructureOptions o;
  const double s = 50.0 / (50.0 + o.shrink);
  const double gain = ExplainedByBins(r, bin, fold, o);
  EXPECT_LE(gain, 0.0);
  EXPECT_NEAR(gain, 1.0 - (1.0 + s) * (1.0 + s), 1e-9);

  // Samples with a negative fold are skipped: an outlier there changes nothing.
  std::vector<double> r2 = r;
  std::vector<int> bin2 = bin;
  std::vector<int> fold2 = fold;
  r2.push_back(1e6);
  bin2.push_back(0);
  fold2.push_back(-1);
  EXPECT_NEAR(ExplainedByBins(r2, bin2, fold2, o), gain, 1e-9);

  // One fold: nothing to hold out, no gain claimed.
  EXPECT_EQ(ExplainedByBins(r, bin, std::vector<int>(n, 0), o), 0.0);
}

TEST(ExplainedByBins, AFewSamplesInABinPredictLittle) {
  // A bin mean learnt from k samples is shrunk by k/(k + shrink): with 2 samples per bin
  // and fold (shrink 20) a true offset of 1 is predicted as 2/22 of it, so the held-out
  // gain is 1 − (1 − 1/11)² ≈ 0.17, where 500 samples (shrink 500/520) recover ≈ 1.
  auto gain_with = [](std::size_t per_cell) {
    const int bins = 4;
    std::vector<double> r;
    std::vector<int> bin;
    std::vector<int> fold;
    for (int b = 0; b < bins; ++b) {
      for (int f = 0; f < 2; ++f) {
        for (std::size_t k = 0; k < per_cell; ++k) {
          r.push_back(b % 2 == 0 ? 1.0 : -1.0);
          bin.push_back(b);
          fold.push_back(f);
        }
      }
    }
    return ExplainedByBins(r, bin, fold);
  };
  const double few = 2.0 / 22.0;
  EXPECT_NEAR(gain_with(2), 1.0 - (1.0 - few) * (1.0 - few), 1e-9);
  const double many = 500.0 / 520.0;
  EXPECT_NEAR(gain_with(500), 1.0 - (1.0 - many) * (1.0 - many), 1e-9);
}

// ---------------------------------------------------------------------- RankWhere

TEST(RankWhere, ChannelsInFirstSeenOrderThenLargestGainFirst) {
  std::vector<WhereEntry> e = {{"force", "base_mm", 0.1, 0.0},
                               {"tip", "time_s", 0.5, 0.0},
                               {"force", "acceleration_mm_s2", 0.9, 0.0},
                               {"tip", "gap_mm", -0.1, 0.0},
                               {"tip", "bend_deg", 0.5, 0.0},
                               {"force", "tip_load_n", -0.3, 0.0}};
  RankWhere(e);
  std::vector<std::pair<std::string, std::string>> got;
  for (const WhereEntry& w : e) got.emplace_back(w.channel, w.variable);
  const std::vector<std::pair<std::string, std::string>> want = {
      {"force", "acceleration_mm_s2"},
      {"force", "base_mm"},
      {"force", "tip_load_n"},
      {"tip", "time_s"},  // equal gains keep their order
      {"tip", "bend_deg"},
      {"tip", "gap_mm"}};
  EXPECT_EQ(got, want);
  std::vector<WhereEntry> empty;
  RankWhere(empty);
  EXPECT_TRUE(empty.empty());
}

}  // namespace
}  // namespace echoservo::lab::residual_structure_test
