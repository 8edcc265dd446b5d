#include "lab/diagnosis.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <numeric>
#include <stdexcept>

#include "hw/effect_registry.h"
#include "lab/candidate_ranking.h"

namespace echoservo::lab {
namespace {

std::string Percent(double fraction) { return PercentText(fraction); }
std::string Num(double v, int decimals) { return FixedText(v, decimals); }

// Starting values for SPEC+effect: the model's fitted values where shared.
std::vector<double> StartFrom(const FitResult& base, const std::vector<std::string>& effects,
                              const LabDataset& ds, const FitOptions& o) {
  hw::TransmissionModel m(FitCatalog(o), effects, ds.trials.front().trial.config);
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
    out.push_back("residual concentrated " + PhaseWords(best->label) + " (" +
                  Percent(share(*best)) + " of the squared error in " +
                  Percent(best->sample_share) + " of the samples)");
  }
  // Speed trend over the bins with data.
  std::vector<double> speed_rms;
  for (const GroupStat& g : d.breakdown.speed) {
    if (g.samples > 50) speed_rms.push_back(rms(g));
  }
  if (speed_rms.size() >= 3) {
    const bool up = std::is_sorted(speed_rms.begin() + 1, speed_rms.end());
    if (up && speed_rms.back() > 2.0 * speed_rms[1]) out.push_back("grows with speed");
    if (speed_rms.front() > 2.0 * speed_rms.back() &&
        speed_rms.front() >= *std::max_element(speed_rms.begin(), speed_rms.end())) {
      out.push_back("largest at low speed");
    }
  }
  // Trends across trials with the configuration.
  std::vector<double> per_trial;
  for (const TrialResult& t : d.base.trials)
    per_trial.push_back(tip ? t.stats.tip_rms_mm : t.stats.force_rms_n);
  struct Axis {
    const char* name;
    double (*get)(const hw::CatheterConfig&);
  };
  const Axis axes[] = {
      {"tip load", [](const hw::CatheterConfig& c) { return c.tip_load_n; }},
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
      out.push_back(std::string(r > 0 ? "grows with " : "falls with ") + a.name +
                    " (r = " + Num(r, 2) + " across trials)");
    }
  }
  return out;
}

}  // namespace

CrossValidation CrossValidate(const std::vector<std::string>& effects, const LabDataset& ds,
                              const FitOptions& o, int folds, const std::vector<double>* initial) {
  if (ds.trials.size() < 2 || folds < 2) {  // no trial to hold out: in-sample (documented)
    const FitResult r = FitModel(effects, ds, o, {}, initial);
    return {r.tip_mse_norm, r.force_mse_norm};
  }
  const std::vector<double> mse = CrossValidateFolds(
      ds.trials.size(), folds,
      [&](const std::vector<std::size_t>& train, const std::vector<std::size_t>& test) {
        const FitResult fit = FitModel(effects, ds, o, train, initial);
        const FitResult held = EvaluateModel(effects, fit.parameters, ds, o, test);
        double m = 0.0;
        for (std::size_t i : test) m += static_cast<double>(ds.trials[i].fit_index.size());
        return FoldScore{{held.tip_mse_norm, held.force_mse_norm}, m};
      });
  return {mse[0], mse[1]};
}

Diagnosis Diagnose(const std::vector<std::string>& model, const LabDataset& ds,
                   const DiagnoseOptions& o) {
  const hw::EffectRegistry& catalog = FitCatalog(o.fit);
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
  std::mutex progress_mutex;
  ForEachInParallel(names.size(), o.threads, [&](std::size_t i) {
    if (o.fit.progress) {
      const std::lock_guard<std::mutex> lock(progress_mutex);
      o.fit.progress("diagnose: fitting " + hw::FormatModelSpec(model) + "+" + names[i]);
    }
    d.candidates[i] = evaluate(names[i]);
  });

  const SignificanceRule rule{o.min_excess, o.min_explained};
  for (Candidate& c : d.candidates) {
    const Judgement j = JudgeCandidate({d.base_cv.tip_mse, d.base_cv.force_mse},
                                       {c.cv.tip_mse, c.cv.force_mse}, rule);
    c.tip_explained = j.explained[0];
    c.force_explained = j.explained[1];
    c.score = j.score;
    c.significant = j.significant;
    c.channel = j.channel == 0 ? "tip" : "force";
  }
  RankCandidates(d.candidates);

  for (Candidate& c : d.candidates) {
    const bool tip = c.channel == "tip";
    const double before = tip ? d.base.overall.tip_rms_mm : d.base.overall.force_rms_n;
    const double after = tip ? c.fit.overall.tip_rms_mm : c.fit.overall.force_rms_n;
    std::string text = std::string(tip ? "tip" : "force") + " RMS " + Num(before, tip ? 4 : 4) +
                       (tip ? " mm" : " N") + " -> " + Num(after, 4) + (tip ? " mm" : " N") + " (" +
                       Percent(before > 0.0 ? (after - before) / before : 0.0) + ")";
    const double explained = tip ? c.tip_explained : c.force_explained;
    text += std::isfinite(explained)
                ? "; explains " + Percent(explained) + " of the held-out excess " +
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
    d.verdict =
        "adequate: no catalog effect explains a significant part of the residual (tip RMS " +
        Num(d.base.overall.tip_rms_mm, 4) + " mm against noise " + Num(ds.noise.tip_mm, 4) +
        " mm, force RMS " + Num(d.base.overall.force_rms_n, 4) + " N against noise " +
        Num(ds.noise.force_n, 4) + " N)";
  } else {
    d.verdict = "missing effect: " + d.candidates.front().effect + " (" +
                d.candidates.front().evidence + ")";
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
    current = hw::ParseModelSpec(hw::FormatModelSpec(current), FitCatalog(o.fit));
  }
  return ladder;
}

}  // namespace echoservo::lab
