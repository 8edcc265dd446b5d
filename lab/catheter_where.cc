#include "lab/catheter_where.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

#include "lab/candidate_ranking.h"

namespace echoservo::lab {
namespace {

constexpr double kRestSpeedMmS = 1.0;
constexpr double kBlockS = 0.5;  // folds of a single-trial dataset

}  // namespace

const std::vector<std::string>& WhereVariables() {
  static const std::vector<std::string> names = {
      "base_mm", "tip_mm",   "velocity_mm_s", "acceleration_mm_s2", "force_n",
      "time_s",  "bend_deg", "gap_mm",        "tip_load_n"};
  return names;
}

const std::vector<double>& ResidualTable::Variable(std::string_view name) const {
  const auto it = std::find(names.begin(), names.end(), name);
  assert(it != names.end());
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
    const hw::Trial& tr = lt.trial;
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
          tr.base_mm[i],       tr.tip_mm[i], v,        lt.acceleration_mm_s2[i],
          tr.force_n[i],       time_s,       bend_deg, tr.config.GapMm(),
          tr.config.tip_load_n};
      for (std::size_t c = 0; c < t.variables.size(); ++c) t.variables[c].push_back(values[c]);
    }
  }
  return t;
}

std::vector<int> DirectionalBins(const ResidualTable& t, std::string_view variable, int bins) {
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
  for (const std::string& name : t.names) {
    const std::vector<int> bins = DirectionalBins(t, name, o.bins);
    for (const Channel& c : channels) {
      WhereEntry e;
      e.channel = c.name;
      e.variable = name;
      e.gain = ExplainedByBins(*c.r, bins, t.fold, o);
      e.explained_fraction = c.excess >= 0.05 ? std::clamp(e.gain / c.excess, 0.0, 1.0) : 0.0;
      out.push_back(e);
    }
  }
  RankWhere(out);
  return out;
}

}  // namespace echoservo::lab
