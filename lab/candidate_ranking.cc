#include "lab/candidate_ranking.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <future>

namespace echoservo::lab {

Judgement JudgeCandidate(const std::vector<double>& base, const std::vector<double>& candidate,
                         const SignificanceRule& rule) {
  assert(!base.empty() && base.size() == candidate.size());
  const std::size_t n = base.size();
  Judgement j;
  std::vector<double> excess(n);
  std::vector<double> drop(n);
  for (std::size_t c = 0; c < n; ++c) {
    excess[c] = std::max(base[c] - 1.0, 0.0);
    drop[c] = base[c] - candidate[c];
    // A fraction of an excess that is (nearly) nothing is noise over noise: undefined.
    j.explained.push_back(excess[c] >= rule.min_excess ? drop[c] / excess[c] : std::nan(""));
    j.score += drop[c];
  }
  double best_part = -1e300;
  for (std::size_t c = 0; c < n; ++c) {
    bool others_ok = true;
    for (std::size_t o = 0; o < n; ++o) {
      if (o != c && !(drop[o] > -std::max(0.1 * excess[o], 0.5))) others_ok = false;
    }
    if (std::isfinite(j.explained[c]) && j.explained[c] >= rule.min_explained && others_ok) {
      j.significant = true;
    }
    const double part = std::isfinite(j.explained[c]) ? j.explained[c] : -1e9;
    if (part > best_part || (part == best_part && drop[c] > drop[j.channel])) {
      best_part = part;
      j.channel = c;
    }
  }
  return j;
}

void ForEachInParallel(std::size_t count, int threads,
                       const std::function<void(std::size_t)>& job) {
  std::atomic<std::size_t> next{0};
  auto worker = [&] {
    for (std::size_t i = next++; i < count; i = next++) job(i);
  };
  std::vector<std::future<void>> workers;
  for (int t = 0; t < std::max(1, threads); ++t)
    workers.push_back(std::async(std::launch::async, worker));
  for (auto& w : workers) w.get();
}

std::vector<double> CrossValidateFolds(std::size_t units, int folds, const FoldFunction& fold,
                                       const std::vector<int>* assignment) {
  assert(units >= 2 && folds >= 2);
  assert(assignment == nullptr || assignment->size() == units);
  const auto k = std::min<std::size_t>(static_cast<std::size_t>(folds), units);
  std::vector<double> sum;
  double weight = 0.0;
  for (std::size_t f = 0; f < k; ++f) {
    std::vector<std::size_t> train;
    std::vector<std::size_t> test;
    for (std::size_t i = 0; i < units; ++i) {
      const std::size_t unit_fold =
          assignment != nullptr ? static_cast<std::size_t>((*assignment)[i]) : i % k;
      (unit_fold == f ? test : train).push_back(i);
    }
    if (test.empty() || train.empty()) continue;
    const FoldScore s = fold(train, test);
    if (sum.empty()) sum.assign(s.mse.size(), 0.0);
    for (std::size_t c = 0; c < s.mse.size(); ++c) sum[c] += s.mse[c] * s.weight;
    weight += s.weight;
  }
  for (double& v : sum) v /= weight;
  return sum;
}

std::vector<int> ShuffledFolds(std::size_t units, int folds) {
  // Order the units by a fixed hash of their index (splitmix64), deal the order mod k.
  auto hash = [](std::uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
  };
  std::vector<std::size_t> order(units);
  for (std::size_t i = 0; i < units; ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return hash(a) < hash(b); });
  const auto k = static_cast<std::size_t>(std::max(folds, 1));
  std::vector<int> fold(units, 0);
  for (std::size_t r = 0; r < units; ++r) fold[order[r]] = static_cast<int>(r % k);
  return fold;
}

std::string PercentText(double fraction) {
  char buf[32];
  const double pct = std::round(100.0 * fraction);
  std::snprintf(buf, sizeof buf, "%.0f%%", pct == 0.0 ? 0.0 : pct);
  return buf;
}

std::string FixedText(double value, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, value);
  return buf;
}

}  // namespace echoservo::lab
