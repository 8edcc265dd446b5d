#include "estimation/diagnosis.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <atomic>
#include <future>
#include <mutex>
#include <numeric>
#include <stdexcept>

#include "hw/effect_registry.h"

namespace echoservo::estimation {
namespace {

const hw::EffectRegistry& Catalog(const FitOptions& o) {
  static const hw::EffectRegistry builtin = hw::EffectRegistry::WithBuiltinEffects();
  return o.registry != nullptr ? *o.registry : builtin;
}

std::string Percent(double fraction) {
  char buf[32];
  const double pct = std::round(100.0 * fraction);
  std::snprintf(buf, sizeof buf, "%.0f%%", pct == 0.0 ? 0.0 : pct);  // never "-0%"
  return buf;
}

std::string Num(double v, int decimals) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// Starting values for SPEC+effect: the model's fitted values where shared.
std::vector<double> StartFrom(const FitResult& base, const std::vector<std::string>& effects,
                              const LabDataset& ds, const FitOptions& o) {
  hw::TransmissionModel m(Catalog(o), effects, ds.trials.front().trial.config);
  std::vector<double> start = m.parameters();
  for (std::size_t i = 0; i < m.parameter_info().size(); ++i) {
    for (const ParameterEstimate& e : base.estimates) {
      if (e.name == m.parameter_info()[i].qualified_name) start[i] = e.value;
    }
  }
  return start;
}

double Pearson(const std::vector<double>& x, const std::vector<double>& y) {
  const auto n = static_cast<double>(x.size());
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n;
  const double my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxx > 0.0 && syy > 0.0 ? sxy / std::sqrt(sxx * syy) : 0.0;
}

std::string PhaseWords(const std::string& phase) {
  if (phase == "after_reversal") return "within 80 ms after reversals";
  if (phase == "acceleration") return "during acceleration";
  if (phase == "constant_velocity") return "at constant velocity";
  return "at rest";
}

// Where the model's residual in `channel` concentrates, in words.
std::vector<std::string> Concentration(const Diagnosis& d, const LabDataset& ds, bool tip) {
  std::vector<std::string> out;
  auto share = [&](const GroupStat& g) { return tip ? g.tip_share : g.force_share; };
  auto rms = [&](const GroupStat& g) { return tip ? g.tip_rms_mm : g.force_rms_n; };
  const GroupStat* best = nullptr;
  for (const GroupStat& g : d.breakdown.phase) {
    if (share(g) >= 0.2 && share(g) > 1.5 * g.sample_share &&
        (best == nullptr || share(g) / g.sample_share > share(*best) / best->sample_share)) {
      best = &g;
    }
  }
  if (best != nullptr) {
    out.push_back("residual concentrated " + PhaseWords(best->label) + " (" + Percent(share(*best)) +
                  " of the squared error in " + Percent(best->sample_share) + " of the samples)");
  }
  // Speed trend over the bins with data.
  std::vector<double> speed_rms;
  for (const GroupStat& g : d.breakdown.speed) {
    if (g.samples > 50) speed_rms.push_back(rms(g));
  }
  if (speed_rms.size() >= 3) {
    const bool up = std::is_sorted(speed_rms.begin() + 1, speed_rms.end());
    if (up && speed_rms.back() > 2.0 * speed_rms[1]) out.push_back("grows with speed");
    if (speed_rms.front() > 2.0 * speed_rms.back() && speed_rms.front() >= *std::max_element(speed_rms.begin(), speed_rms.end())) {
      out.push_back("largest at low speed");
    }
  }
  // Trends across trials with the configuration.
  std::vector<double> per_trial;
  for (const TrialResult& t : d.base.trials) per_trial.push_back(tip ? t.stats.tip_rms_mm : t.stats.force_rms_n);
  struct Axis {
    const char* name;
    double (*get)(const hw::CatheterConfig&);
  };
  const Axis axes[] = {{"tip load", [](const hw::CatheterConfig& c) { return c.tip_load_n; }},
                       {"gap", [](const hw::CatheterConfig& c) { return c.GapMm(); }},
                       {"total bend angle", [](const hw::CatheterConfig& c) { return c.TotalBendRad(); }}};
  for (const Axis& a : axes) {
    std::vector<double> x;
    for (const LabTrial& t : ds.trials) x.push_back(a.get(t.trial.config));
    std::vector<double> distinct = x;
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    if (distinct.size() < 3) continue;
    const double r = Pearson(x, per_trial);
    if (std::abs(r) >= 0.6) {
      out.push_back(std::string(r > 0 ? "grows with " : "falls with ") + a.name + " (r = " + Num(r, 2) +
                    " across trials)");
    }
  }
  return out;
}

}  // namespace

CrossValidation CrossValidate(const std::vector<std::string>& effects, const LabDataset& ds, const FitOptions& o,
                              int folds, const std::vector<double>* initial) {
  const std::size_t n = ds.trials.size();
  CrossValidation cv;
  if (n < 2 || folds < 2) {  // no trial to hold out: in-sample (documented)
    const FitResult r = FitModel(effects, ds, o, {}, initial);
    return {r.tip_mse_norm, r.force_mse_norm};
  }
  const int k = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(folds), n));
  double tip = 0.0, force = 0.0, weight = 0.0;
  for (int f = 0; f < k; ++f) {
    std::vector<std::size_t> train, test;
    for (std::size_t i = 0; i < n; ++i) (static_cast<int>(i % static_cast<std::size_t>(k)) == f ? test : train).push_back(i);
    const FitResult fit = FitModel(effects, ds, o, train, initial);
    const FitResult held = EvaluateModel(effects, fit.parameters, ds, o, test);
    double m = 0.0;
    for (std::size_t i : test) m += static_cast<double>(ds.trials[i].fit_index.size());
    tip += held.tip_mse_norm * m;
    force += held.force_mse_norm * m;
    weight += m;
  }
  cv.tip_mse = tip / weight;
  cv.force_mse = force / weight;
  return cv;
}

Diagnosis Diagnose(const std::vector<std::string>& model, const LabDataset& ds, const DiagnoseOptions& o) {
  const hw::EffectRegistry& catalog = Catalog(o.fit);
  Diagnosis d;
  d.model = model;
  d.base = FitModel(model, ds, o.fit);
  d.base_cv = CrossValidate(model, ds, o.fit, o.folds, &d.base.parameters);
  d.breakdown = ComputeBreakdown(ds, d.base);

  std::vector<std::string> names = o.candidates;
  if (names.empty()) {
    for (const std::string& e : catalog.Names()) {
      if (std::find(model.begin(), model.end(), e) == model.end()) names.push_back(e);
    }
  }
  auto evaluate = [&](const std::string& effect) {
    Candidate c;
    c.effect = effect;
    std::vector<std::string> effects = model;
    effects.push_back(effect);
    effects = hw::ParseModelSpec(hw::FormatModelSpec(effects), catalog);  // pipeline order
    const std::vector<double> start = StartFrom(d.base, effects, ds, o.fit);
    FitOptions fo = o.fit;
    fo.threads = 1;
    fo.progress = nullptr;
    c.fit = FitModel(effects, ds, fo, {}, &start);
    c.cv = CrossValidate(effects, ds, fo, o.folds, &c.fit.parameters);
    return c;
  };
  // Fit the candidates on `threads` workers pulling from a shared queue.
  d.candidates.resize(names.size());
  std::atomic<std::size_t> next{0};
  std::mutex progress_mutex;
  auto worker = [&] {
    for (std::size_t i = next++; i < names.size(); i = next++) {
      if (o.fit.progress) {
        const std::lock_guard<std::mutex> lock(progress_mutex);
        o.fit.progress("diagnose: fitting " + hw::FormatModelSpec(model) + "+" + names[i]);
      }
      d.candidates[i] = evaluate(names[i]);
    }
  };
  std::vector<std::future<void>> workers;
  for (int t = 0; t < std::max(1, o.threads); ++t) workers.push_back(std::async(std::launch::async, worker));
  for (auto& w : workers) w.get();

  const double tip_excess = std::max(d.base_cv.tip_mse - 1.0, 0.0);
  const double force_excess = std::max(d.base_cv.force_mse - 1.0, 0.0);
  for (Candidate& c : d.candidates) {
    const double tip_drop = d.base_cv.tip_mse - c.cv.tip_mse;
    const double force_drop = d.base_cv.force_mse - c.cv.force_mse;
    // A fraction of an excess that is (nearly) nothing is noise over noise: undefined.
    c.tip_explained = tip_excess >= o.min_excess ? tip_drop / tip_excess : std::nan("");
    c.force_explained = force_excess >= o.min_excess ? force_drop / force_excess : std::nan("");
    c.score = tip_drop + force_drop;
    const bool tip_ok = std::isfinite(c.tip_explained) && c.tip_explained >= o.min_explained &&
                        force_drop > -std::max(0.1 * force_excess, 0.5);
    const bool force_ok = std::isfinite(c.force_explained) && c.force_explained >= o.min_explained &&
                          tip_drop > -std::max(0.1 * tip_excess, 0.5);
    c.significant = tip_ok || force_ok;
    const double tip_part = std::isfinite(c.tip_explained) ? c.tip_explained : -1e9;
    const double force_part = std::isfinite(c.force_explained) ? c.force_explained : -1e9;
    c.channel = tip_part == force_part ? (tip_drop >= force_drop ? "tip" : "force")
                                       : (tip_part > force_part ? "tip" : "force");
  }
  std::stable_sort(d.candidates.begin(), d.candidates.end(), [](const Candidate& a, const Candidate& b) {
    if (a.significant != b.significant) return a.significant;
    return a.score > b.score;
  });

  for (Candidate& c : d.candidates) {
    const bool tip = c.channel == "tip";
    const double before = tip ? d.base.overall.tip_rms_mm : d.base.overall.force_rms_n;
    const double after = tip ? c.fit.overall.tip_rms_mm : c.fit.overall.force_rms_n;
    std::string text = std::string(tip ? "tip" : "force") + " RMS " + Num(before, tip ? 4 : 4) +
                       (tip ? " mm" : " N") + " -> " + Num(after, 4) + (tip ? " mm" : " N") + " (" +
                       Percent(before > 0.0 ? (after - before) / before : 0.0) + ")";
    const double explained = tip ? c.tip_explained : c.force_explained;
    text += std::isfinite(explained) ? "; explains " + Percent(explained) + " of the held-out excess " +
                                           (tip ? "tip" : "force") + " residual"
                                     : "; the model leaves no excess over the noise in this channel";
    if (c.significant) {
      for (const std::string& s : Concentration(d, ds, tip)) text += "; " + s;
      text += "; expected signature: " + std::string(catalog.Create(c.effect)->signature());
    }
    c.evidence = text;
  }

  d.adequate = d.candidates.empty() || !d.candidates.front().significant;
  if (d.adequate) {
    d.verdict = "adequate: no catalog effect explains a significant part of the residual (tip RMS " +
                Num(d.base.overall.tip_rms_mm, 4) + " mm against noise " + Num(ds.noise.tip_mm, 4) +
                " mm, force RMS " + Num(d.base.overall.force_rms_n, 4) + " N against noise " +
                Num(ds.noise.force_n, 4) + " N)";
  } else {
    d.verdict = "missing effect: " + d.candidates.front().effect + " (" + d.candidates.front().evidence + ")";
  }
  return d;
}

std::vector<LadderStep> ErrorLadder(const std::vector<std::string>& model, const LabDataset& ds,
                                    const DiagnoseOptions& o, int max_rounds) {
  std::vector<LadderStep> ladder;
  std::vector<std::string> current = model;
  for (int round = 0; round <= max_rounds; ++round) {
    LadderStep step;
    step.model = current;
    step.diagnosis = Diagnose(current, ds, o);
    const bool done = step.diagnosis.adequate || round == max_rounds;
    const std::string next = done ? std::string() : step.diagnosis.candidates.front().effect;
    ladder.push_back(std::move(step));
    if (done) break;
    current.push_back(next);
    current = hw::ParseModelSpec(hw::FormatModelSpec(current), Catalog(o.fit));
  }
  return ladder;
}

}  // namespace echoservo::estimation
