#include "lab/residual_structure.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numeric>

namespace echoservo::lab {

std::vector<int> QuantileBins(const std::vector<double>& x, int bins) {
  const std::size_t n = x.size();
  std::vector<int> out(n, 0);
  if (n == 0 || bins <= 1) return out;
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return x[a] < x[b]; });
  // Walk the sorted values; a new bin starts once the current one holds its share of the
  // samples and the value changes (ties stay together).
  const double per_bin = static_cast<double>(n) / bins;
  int bin = 0;
  std::size_t in_bin = 0;
  for (std::size_t k = 0; k < n; ++k) {
    if (k > 0 && x[order[k]] != x[order[k - 1]] && in_bin >= per_bin && bin < bins - 1) {
      ++bin;
      in_bin = 0;
    }
    out[order[k]] = bin;
    ++in_bin;
  }
  return out;
}

double ExplainedByBins(const std::vector<double>& r, const std::vector<int>& bin,
                       const std::vector<int>& fold, const StructureOptions& o) {
  assert(r.size() == bin.size() && r.size() == fold.size());
  const int bins = bin.empty() ? 0 : *std::max_element(bin.begin(), bin.end()) + 1;
  const int folds = fold.empty() ? 0 : *std::max_element(fold.begin(), fold.end()) + 1;
  if (bins <= 1 || folds < 2) return 0.0;
  // Sums per (fold, bin); a held-out fold is predicted from the totals minus its own.
  const auto cells = static_cast<std::size_t>(folds) * static_cast<std::size_t>(bins);
  std::vector<double> sum(cells, 0.0);
  std::vector<double> count(cells, 0.0);
  std::vector<double> total_sum(static_cast<std::size_t>(bins), 0.0);
  std::vector<double> total_count(static_cast<std::size_t>(bins), 0.0);
  for (std::size_t i = 0; i < r.size(); ++i) {
    if (fold[i] < 0 || bin[i] < 0) continue;
    const auto cell = static_cast<std::size_t>(fold[i]) * static_cast<std::size_t>(bins) +
                      static_cast<std::size_t>(bin[i]);
    sum[cell] += r[i];
    count[cell] += 1.0;
    total_sum[static_cast<std::size_t>(bin[i])] += r[i];
    total_count[static_cast<std::size_t>(bin[i])] += 1.0;
  }
  double gain = 0.0;
  double used = 0.0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    if (fold[i] < 0 || bin[i] < 0) continue;
    const auto b = static_cast<std::size_t>(bin[i]);
    const auto cell = static_cast<std::size_t>(fold[i]) * static_cast<std::size_t>(bins) + b;
    const double n = total_count[b] - count[cell];
    const double mean = n > 0.0 ? (total_sum[b] - sum[cell]) / (n + o.shrink) : 0.0;
    // Residual before: r; after: r − mean.
    gain += r[i] * r[i] - (r[i] - mean) * (r[i] - mean);
    used += 1.0;
  }
  return used > 0.0 ? gain / used : 0.0;
}

double ExplainedByVariable(const std::vector<double>& r, const std::vector<double>& x,
                           const std::vector<int>& fold, const StructureOptions& o) {
  return ExplainedByBins(r, QuantileBins(x, o.bins), fold, o);
}

void RankWhere(std::vector<WhereEntry>& entries) {
  std::vector<std::string> channels;
  for (const WhereEntry& e : entries) {
    if (std::find(channels.begin(), channels.end(), e.channel) == channels.end())
      channels.push_back(e.channel);
  }
  auto rank = [&](const std::string& c) {
    return std::find(channels.begin(), channels.end(), c) - channels.begin();
  };
  std::stable_sort(entries.begin(), entries.end(), [&](const WhereEntry& a, const WhereEntry& b) {
    if (a.channel != b.channel) return rank(a.channel) < rank(b.channel);
    return a.gain > b.gain;
  });
}

}  // namespace echoservo::lab
