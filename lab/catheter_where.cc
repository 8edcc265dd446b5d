#include "lab/catheter_where.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>

#include "lab/candidate_ranking.h"

namespace echoservo::lab {
namespace {

constexpr double kRestSpeedMmS = 1.0;
constexpr double kBlockS = 0.5;  // folds of a single-trial dataset
// A pair: a trial-level variable in up to 4 quantile bins × a sample-level one in 6, each
// with the direction of motion.
constexpr int kPairTrialBins = 4;
constexpr int kPairSampleBins = 6;
// A pair must explain this much more than either of its variables alone (noise variances,
// and share of the channel's excess).
constexpr double kPairMargin = 0.05;
constexpr double kPairExcessShare = 0.1;

const std::vector<std::string>& TrialLevelVariables() {
  static const std::vector<std::string> names = {"bend_deg", "gap_mm", "tip_load_n"};
  return names;
}

const std::vector<std::string>& PairSampleVariables() {
  static const std::vector<std::string> names = {"base_mm", "velocity_mm_s", "acceleration_mm_s2",
                                                 "time_s"};
  return names;
}

}  // namespace

const std::vector<std::string>& WhereVariables() {
  static const std::vector<std::string> names = {
      "base_mm",       "tip_mm", "tip_model_mm", "velocity_mm_s", "acceleration_mm_s2", "force_n",
      "force_model_n", "time_s", "bend_deg",     "gap_mm",        "tip_load_n"};
  return names;
}

bool CircularFor(std::string_view channel, std::string_view variable) {
  return (channel == "tip" && variable == "tip_mm") ||
         (channel == "force" && variable == "force_n");
}

bool IsPair(std::string_view variable) { return variable.find('*') != std::string_view::npos; }

std::pair<std::string, std::string> SplitPair(std::string_view variable) {
  const std::size_t star = variable.find('*');
  assert(star != std::string_view::npos);
  return {std::string(variable.substr(0, star)), std::string(variable.substr(star + 1))};
}

const std::vector<double>& ResidualTable::Variable(std::string_view name) const {
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) throw std::logic_error("residual table: no variable " + std::string(name));
  return variables[static_cast<std::size_t>(it - names.begin())];
}

ResidualTable BuildResidualTable(const LabDataset& ds, const std::vector<Prediction>& held_out,
                                 int folds) {
  assert(held_out.size() == ds.trials.size());
  ResidualTable t;
  t.names = WhereVariables();
  t.variables.resize(t.names.size());
  const std::size_t n = ds.residual_samples();
  for (auto& v : t.variables) v.reserve(n);
  const bool by_trial = ds.trials.size() >= 2;
  const std::vector<int> trial_fold = ShuffledFolds(ds.trials.size(), std::max(2, folds));
  for (std::size_t j = 0; j < ds.trials.size(); ++j) {
    const LabTrial& lt = ds.trials[j];
    const formats::Trial& tr = lt.trial;
    const Prediction& p = held_out[j];
    const double bend_deg = tr.config.TotalBendRad() * 180.0 / std::numbers::pi;
    for (std::size_t i : lt.fit_index) {
      const double time_s = tr.t_s[i] - tr.t_s.front();
      const double v = lt.velocity_mm_s[i];
      t.trial.push_back(j);
      t.index.push_back(i);
      t.fold.push_back(by_trial ? trial_fold[j]
                                : static_cast<int>(static_cast<long>(time_s / kBlockS) % 2));
      t.direction.push_back(std::abs(v) < kRestSpeedMmS ? 0 : (v > 0.0 ? 1 : -1));
      t.tip.push_back((p.tip_mm[i] - tr.tip_mm[i]) / ds.noise.tip_mm);
      t.force.push_back((p.force_n[i] - tr.force_n[i]) / ds.noise.force_n);
      const double values[] = {
          tr.base_mm[i],       tr.tip_mm[i], p.tip_mm[i], v,        lt.acceleration_mm_s2[i],
          tr.force_n[i],       p.force_n[i], time_s,      bend_deg, tr.config.GapMm(),
          tr.config.tip_load_n};
      for (std::size_t c = 0; c < t.variables.size(); ++c) t.variables[c].push_back(values[c]);
    }
  }
  return t;
}

std::vector<int> DirectionalBins(const ResidualTable& t, std::string_view variable, int bins) {
  if (IsPair(variable)) {
    const auto [slow, fast] = SplitPair(variable);
    const std::vector<int> a = QuantileBins(t.Variable(slow), kPairTrialBins);
    std::vector<int> b = DirectionalBins(t, fast, kPairSampleBins);
    const int nb = b.empty() ? 0 : *std::max_element(b.begin(), b.end()) + 1;
    for (std::size_t i = 0; i < b.size(); ++i) b[i] += nb * a[i];
    return b;
  }
  std::vector<int> b = QuantileBins(t.Variable(variable), bins);
  // Velocity already carries the direction.
  if (variable == "velocity_mm_s") return b;
  for (std::size_t i = 0; i < b.size(); ++i) b[i] = 3 * b[i] + (t.direction[i] + 1);
  return b;
}

std::vector<WhereEntry> LocateResidual(const ResidualTable& t, double tip_excess,
                                       double force_excess, const StructureOptions& o) {
  std::vector<WhereEntry> out;
  struct Channel {
    const char* name;
    const std::vector<double>* r;
    double excess;
  };
  const Channel channels[] = {{"tip", &t.tip, tip_excess}, {"force", &t.force, force_excess}};
  auto entry = [&](const Channel& c, const std::string& name, double gain) {
    WhereEntry e;
    e.channel = c.name;
    e.variable = name;
    e.gain = gain;
    e.explained_fraction = c.excess >= 0.05 ? std::clamp(gain / c.excess, 0.0, 1.0) : 0.0;
    return e;
  };
  std::map<std::pair<std::string, std::string>, double> single;
  for (const std::string& name : t.names) {
    const std::vector<int> bins = DirectionalBins(t, name, o.bins);
    for (const Channel& c : channels) {
      // A channel's own measurement is part of its residual: it always correlates and
      // says nothing (the model's prediction of the channel stands in for it).
      if (CircularFor(c.name, name)) continue;
      const double gain = ExplainedByBins(*c.r, bins, t.fold, o);
      single[{c.name, name}] = gain;
      out.push_back(entry(c, name, gain));
    }
  }
  // Pairs of a trial-level variable and a sample-level one: kept when the pair explains
  // clearly more than either variable alone (an interaction, such as friction that grows
  // with speed in proportion to the bend).
  for (const std::string& slow : TrialLevelVariables()) {
    std::vector<double> distinct = t.Variable(slow);
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    if (distinct.size() < 2) continue;
    // The best pair of each trial-level variable per channel (its pairs with the sample-level
    // variables largely repeat one another).
    std::map<std::string, WhereEntry> best;
    for (const std::string& fast : PairSampleVariables()) {
      const std::string name = slow + "*" + fast;
      const std::vector<int> bins = DirectionalBins(t, name, o.bins);
      for (const Channel& c : channels) {
        if (CircularFor(c.name, fast)) continue;
        const double gain = ExplainedByBins(*c.r, bins, t.fold, o);
        const double alone = std::max(single[{c.name, slow}], single[{c.name, fast}]);
        if (gain <= alone + std::max(kPairMargin, kPairExcessShare * c.excess)) continue;
        const auto it = best.find(c.name);
        if (it == best.end() || gain > it->second.gain) best[c.name] = entry(c, name, gain);
      }
    }
    for (const auto& [channel, e] : best) out.push_back(e);
  }
  RankWhere(out);
  return out;
}

}  // namespace echoservo::lab
