#include "lab/diagnosis.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <numeric>
#include <stdexcept>

#include "hw/effect_registry.h"
#include "lab/candidate_ranking.h"
#include "lab/catheter_where.h"
#include "lab/effect_discovery.h"
#include "lab/shape_learning.h"

namespace echoservo::lab {
namespace {

std::string Percent(double fraction) { return PercentText(fraction); }
std::string Num(double v, int decimals) { return FixedText(v, decimals); }

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
    double (*get)(const formats::CatheterConfig&);
  };
  const Axis axes[] = {
      {"tip load", [](const formats::CatheterConfig& c) { return c.tip_load_n; }},
      {"gap", [](const formats::CatheterConfig& c) { return c.GapMm(); }},
      {"total bend angle", [](const formats::CatheterConfig& c) { return c.TotalBendRad(); }}};
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

std::vector<double> StartingValues(const FitResult& base, const std::vector<std::string>& effects,
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

CrossValidation CrossValidate(const std::vector<std::string>& effects, const LabDataset& ds,
                              const FitOptions& o, int folds, const std::vector<double>* initial,
                              bool keep_predictions) {
  CrossValidation cv;
  if (ds.trials.size() < 2 || folds < 2) {  // no trial to hold out: in-sample (documented)
    FitResult r = FitModel(effects, ds, o, {}, initial);
    cv.tip_mse = r.tip_mse_norm;
    cv.force_mse = r.force_mse_norm;
    if (keep_predictions) {
      for (TrialResult& t : r.trials) cv.held_out.push_back(std::move(t.prediction));
    }
    return cv;
  }
  if (keep_predictions) cv.held_out.resize(ds.trials.size());
  const std::vector<int> assignment = ShuffledFolds(ds.trials.size(), folds);
  const std::vector<double> mse = CrossValidateFolds(
      ds.trials.size(), folds,
      [&](const std::vector<std::size_t>& train, const std::vector<std::size_t>& test) {
        const FitResult fit = FitModel(effects, ds, o, train, initial);
        FitResult held = EvaluateModel(effects, fit.parameters, ds, o, test);
        double m = 0.0;
        for (std::size_t i : test) m += static_cast<double>(ds.trials[i].fit_index.size());
        if (keep_predictions) {
          for (std::size_t k = 0; k < test.size(); ++k)
            cv.held_out[test[k]] = std::move(held.trials[k].prediction);
        }
        return FoldScore{{held.tip_mse_norm, held.force_mse_norm}, m};
      },
      &assignment);
  cv.tip_mse = mse[0];
  cv.force_mse = mse[1];
  return cv;
}

namespace {

// Held-out RMS of a channel (mm or N) from its score in noise variances.
double HeldOutRms(double mse, double noise) { return std::sqrt(std::max(mse, 0.0)) * noise; }

std::string ChannelWords(const Diagnosis& d, const LabDataset& ds, bool tip) {
  const double mse = tip ? d.base_cv.tip_mse : d.base_cv.force_mse;
  const double noise = tip ? ds.noise.tip_mm : ds.noise.force_n;
  const char* unit = tip ? " mm" : " N";
  return std::string(tip ? "tip" : "force") + " held-out RMS " + Num(HeldOutRms(mse, noise), 4) +
         unit + " against noise " + Num(noise, 4) + unit + " (" +
         Num(std::sqrt(std::max(mse, 0.0)), 1) + "x)";
}

// "force: acceleration_mm_s2 explains 83% of the excess" for the top variable of a channel.
std::string WhereWords(const std::vector<WhereEntry>& where, const std::string& channel) {
  for (const WhereEntry& e : where) {
    if (e.channel == channel) {
      return channel + " residual varies most with " + e.variable + " (explains " +
             Percent(e.explained_fraction) + " of its held-out excess)";
    }
  }
  return "";
}

double TopGain(const std::vector<WhereEntry>& where, const std::string& channel) {
  for (const WhereEntry& e : where)
    if (e.channel == channel) return e.gain;
  return 0.0;
}

// Writes the proposal's effect file into `o.propose_dir` (when set) and names it in its SPEC.
void WriteProposal(Proposal& p, const DiagnoseOptions& o) {
  // The model without the proposed effects (the catalog's and the user's effects only).
  std::vector<std::string> model = p.effects;
  std::erase(model, p.effect.name);
  for (const hw::EffectFileSpec& e : p.earlier) std::erase(model, e.name);
  std::string spec = hw::FormatModelSpec(model, FitCatalog(o.fit));
  auto write = [&](hw::EffectFileSpec& e) {
    if (o.propose_dir.empty()) {
      spec += "+" + e.name;
      return std::string();
    }
    std::filesystem::create_directories(o.propose_dir);
    const std::filesystem::path file = o.propose_dir / (e.name + ".json");
    hw::WriteEffectFile(file, e);
    e.path = file.string();
    spec += "+@" + e.path;
    return e.path;
  };
  for (hw::EffectFileSpec& e : p.earlier) write(e);
  p.file = write(p.effect);
  p.spec = spec;
}

}  // namespace

Diagnosis Diagnose(const std::vector<std::string>& model, const LabDataset& ds,
                   const DiagnoseOptions& o) {
  const hw::EffectRegistry& catalog = FitCatalog(o.fit);
  Diagnosis d;
  d.model = model;
  d.base = FitModel(model, ds, o.fit);
  d.base_cv = CrossValidate(model, ds, o.fit, o.folds, &d.base.parameters, true);
  d.breakdown = ComputeBreakdown(ds, d.base);
  d.tip_excess = d.base_cv.tip_mse - 1.0;
  d.force_excess = d.base_cv.force_mse - 1.0;
  const ResidualTable residuals = BuildResidualTable(ds, d.base_cv.held_out, o.folds);
  d.where = LocateResidual(residuals, d.tip_excess, d.force_excess);

  // Candidates: every catalog effect not in the model is added; then, with `swappable`,
  // the `swap_candidates` best additions are also tried in place of each swappable effect
  // (a replacement worth making is an effect that helps as an addition too).
  struct Change {
    std::string effect;
    std::string replaces;
  };
  std::vector<std::string> names;
  for (const std::string& e : o.candidates) {  // the user's list, less what the model has
    if (std::find(model.begin(), model.end(), e) == model.end()) names.push_back(e);
  }
  if (o.candidates.empty()) {
    for (const std::string& e : catalog.Names()) {
      if (std::find(model.begin(), model.end(), e) == model.end()) names.push_back(e);
    }
  }
  const std::vector<double> base_scores = {d.base_cv.tip_mse, d.base_cv.force_mse};
  const SignificanceRule rule{o.min_excess, o.min_explained};
  auto evaluate = [&](const Change& change) {
    Candidate c;
    c.effect = change.effect;
    c.replaces = change.replaces;
    std::vector<std::string> effects = model;
    std::erase(effects, change.replaces);
    effects.push_back(change.effect);
    effects = hw::ParseModelSpec(hw::FormatModelSpec(effects), catalog);  // pipeline order
    const std::vector<double> start = StartingValues(d.base, effects, ds, o.fit);
    FitOptions fo = o.fit;
    fo.threads = 1;
    fo.progress = nullptr;
    c.fit = FitModel(effects, ds, fo, {}, &start);
    c.cv = CrossValidate(effects, ds, fo, o.folds, &c.fit.parameters);
    const Judgement j = JudgeCandidate(base_scores, {c.cv.tip_mse, c.cv.force_mse}, rule);
    c.tip_explained = j.explained[0];
    c.force_explained = j.explained[1];
    c.score = j.score;
    c.significant = j.significant;
    c.channel = j.channel == 0 ? "tip" : "force";
    return c;
  };
  // Fit the changes on `threads` workers pulling from a shared queue.
  std::mutex progress_mutex;
  auto evaluate_all = [&](const std::vector<Change>& changes) {
    std::vector<Candidate> out(changes.size());
    ForEachInParallel(changes.size(), o.threads, [&](std::size_t i) {
      if (o.fit.progress) {
        const std::lock_guard<std::mutex> lock(progress_mutex);
        o.fit.progress("diagnose: fitting " + hw::FormatModelSpec(model) +
                       (changes[i].replaces.empty() ? "" : "-" + changes[i].replaces) + "+" +
                       changes[i].effect);
      }
      out[i] = evaluate(changes[i]);
    });
    return out;
  };
  std::vector<Change> additions;
  for (const std::string& e : names) additions.push_back({e, ""});
  d.candidates = evaluate_all(additions);
  std::vector<std::string> swappable;
  for (const std::string& r : o.swappable) {
    if (std::find(model.begin(), model.end(), r) != model.end()) swappable.push_back(r);
  }
  if (!swappable.empty()) {
    std::vector<Candidate> best = d.candidates;
    RankCandidates(best);
    std::vector<Change> swaps;
    for (std::size_t k = 0; k < best.size() && k < static_cast<std::size_t>(o.swap_candidates);
         ++k) {
      for (const std::string& r : swappable) swaps.push_back({best[k].effect, r});
    }
    for (Candidate& c : evaluate_all(swaps)) d.candidates.push_back(std::move(c));
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

  const double close_mse = o.close_ratio * o.close_ratio;
  auto closes = [&](double tip_mse, double force_mse) {
    return tip_mse <= close_mse && force_mse <= close_mse;
  };
  for (Candidate& c : d.candidates) c.closes_gap = closes(c.cv.tip_mse, c.cv.force_mse);
  const bool significant = !d.candidates.empty() && d.candidates.front().significant;
  bool missing = significant && d.candidates.front().closes_gap;
  if (significant && !missing && d.candidates.front().replaces.empty()) {
    // Two effects at once: the best candidate may close the gap together with the best
    // significant candidate of the other channel (each then named in its own round).
    const Candidate& best = d.candidates.front();
    for (const Candidate& other : d.candidates) {
      if (!other.significant || !other.replaces.empty() || other.channel == best.channel ||
          other.effect == best.effect)
        continue;
      std::vector<std::string> both = model;
      both.push_back(best.effect);
      both.push_back(other.effect);
      both = hw::ParseModelSpec(hw::FormatModelSpec(both), catalog);
      if (o.fit.progress)
        o.fit.progress("diagnose: fitting " + hw::FormatModelSpec(both) + " (two effects)");
      const std::vector<double> start = StartingValues(best.fit, both, ds, o.fit);
      const FitResult fit = FitModel(both, ds, o.fit, {}, &start);
      const CrossValidation cv = CrossValidate(both, ds, o.fit, o.folds, &fit.parameters);
      if (closes(cv.tip_mse, cv.force_mse)) {
        missing = true;
        d.closes_with = other.effect;
      }
      break;
    }
  }
  const bool tip_left = d.tip_excess >= o.min_excess || TopGain(d.where, "tip") >= o.min_structure;
  const bool force_left =
      d.force_excess >= o.min_excess || TopGain(d.where, "force") >= o.min_structure;
  const std::string figures = ChannelWords(d, ds, true) + ", " + ChannelWords(d, ds, false);
  // Beyond the catalog: the discovery library, then a learnt shape and its formula, on top of
  // `m` (fit and held-out scores with predictions given); the better proposal is kept.
  auto propose = [&](const std::vector<std::string>& m, const FitResult& fit,
                     const CrossValidation& cv) -> std::optional<Proposal> {
    const ResidualTable table = BuildResidualTable(ds, cv.held_out, o.folds);
    Diagnosis beyond;
    beyond.model = m;
    beyond.base = fit;
    beyond.base_cv = cv;
    beyond.tip_excess = cv.tip_mse - 1.0;
    beyond.force_excess = cv.force_mse - 1.0;
    beyond.where =
        &m == &model ? d.where : LocateResidual(table, beyond.tip_excess, beyond.force_excess);
    // With learning to follow, the library's term is kept on the selection of a large
    // dataset and refitted on every trial only if it is kept.
    std::optional<Proposal> library =
        o.discover ? DiscoverEffect(m, ds, beyond, table, o, {}, !o.learn) : std::nullopt;
    auto full = [&](Proposal& p) {
      if (p.cv_trials < ds.trials.size()) RefitProposal(p, m, ds, o);
    };
    if (library && closes(library->cv.tip_mse, library->cv.force_mse)) full(*library);
    std::optional<Proposal> out = library;
    if (o.learn && !(library && library->cv_trials == ds.trials.size() &&
                     closes(library->cv.tip_mse, library->cv.force_mse))) {
      std::optional<Proposal> learned =
          LearnMissingTerm(m, ds, fit, cv, table, beyond.where, o, d.learning);
      if (learned && (!library || learned->cv.tip_mse + learned->cv.force_mse <
                                      library->cv.tip_mse + library->cv.force_mse)) {
        out = std::move(learned);
      } else if (library) {
        full(*out);
        if (learned) {
          d.learning.proposed = "";
          d.learning.note += "; the discovery library's term fits better and is proposed";
        }
      }
    }
    // A second term, learnt on top of the first, while a channel keeps more than the noise
    // allows (two effects the data hold at once).
    if (o.learn && out && !closes(out->cv.tip_mse, out->cv.force_mse)) {
      hw::EffectRegistry registry = FitCatalog(o.fit);
      hw::RegisterEffectSpec(registry, out->effect);
      DiagnoseOptions o2 = o;
      o2.fit.registry = &registry;
      const std::vector<std::string>& m2 = out->effects;
      if (o.fit.progress) o.fit.progress("learning: a second term on top of " + out->effect.name);
      const CrossValidation cv2 =
          CrossValidate(m2, ds, o2.fit, o.folds, &out->fit.parameters, true);
      const ResidualTable table2 = BuildResidualTable(ds, cv2.held_out, o.folds);
      const std::vector<WhereEntry> where2 =
          LocateResidual(table2, cv2.tip_mse - 1.0, cv2.force_mse - 1.0);
      ShapeLearning learning2;
      std::optional<Proposal> second =
          LearnMissingTerm(m2, ds, out->fit, cv2, table2, where2, o2, learning2);
      if (second &&
          second->cv.tip_mse + second->cv.force_mse < out->cv.tip_mse + out->cv.force_mse - 0.05) {
        second->earlier = out->earlier;
        second->earlier.push_back(out->effect);
        second->equation = out->equation + "; then " + second->equation;
        second->terms.insert(second->terms.begin(), out->terms.begin(), out->terms.end());
        d.learning.note += "; a second term was learnt on top of it: " + learning2.note;
        for (LearnedShape& l : learning2.shapes) d.learning.shapes.push_back(std::move(l));
        for (FormulaCandidate& f : learning2.formulas) d.learning.formulas.push_back(std::move(f));
        out = std::move(second);
      }
    }
    return out;
  };
  auto total = [](const Proposal& p) { return p.cv.tip_mse + p.cv.force_mse; };
  if (missing) {
    const Candidate& best = d.candidates.front();
    d.verdict = "missing_effect";
    d.summary = "missing effect: " + best.effect +
                (best.replaces.empty() ? "" : " (replacing " + best.replaces + ")") + " (" +
                best.evidence + ")";
    if (!d.closes_with.empty())
      d.summary += "; together with " + d.closes_with + " (next) it brings every channel within " +
                   Num(o.close_ratio, 1) + "x the noise floor on held-out trials";
  } else if (significant) {
    // Significant but short of the noise floor: say how much it explains, then learn what
    // remains on top of it.
    const Candidate& best = d.candidates.front();
    const bool tip = best.channel == "tip";
    d.partial = best.effect;
    d.partial_fraction = tip ? best.tip_explained : best.force_explained;
    d.verdict = "unexplained";
    d.summary = "unexplained: " + best.effect + " partly explains " + Percent(d.partial_fraction) +
                " of the held-out " + best.channel + " excess but leaves tip " +
                Num(std::sqrt(std::max(best.cv.tip_mse, 0.0)), 1) + "x and force " +
                Num(std::sqrt(std::max(best.cv.force_mse, 0.0)), 1) +
                "x the noise floor on held-out trials (" + figures + " without it)";
    if (o.discover || o.learn) {
      // What remains is learnt on top of the candidate, and also without it (a candidate that
      // only partly explains may be the wrong physics absorbing part of another law); the
      // proposal with the lower held-out residual is kept.
      std::vector<std::string> with = model;
      std::erase(with, best.replaces);
      with.push_back(best.effect);
      with = hw::ParseModelSpec(hw::FormatModelSpec(with), catalog);
      const CrossValidation cv =
          CrossValidate(with, ds, o.fit, o.folds, &best.fit.parameters, true);
      std::optional<Proposal> on_top = propose(with, best.fit, cv);
      ShapeLearning learning_on_top = std::move(d.learning);
      std::optional<Proposal> alone = propose(model, d.base, d.base_cv);
      // Without the candidate is preferred unless on top of it is clearly better (fewer
      // effects for the same held-out figures: 0.05 noise variances).
      const bool use_alone = alone && (!on_top || total(*alone) <= total(*on_top) + 0.05);
      if (!use_alone) {
        d.proposal = std::move(on_top);
        d.learning = std::move(learning_on_top);
      } else {
        d.proposal = std::move(alone);
      }
      d.summary += !d.proposal ? "; nothing learnt explains what remains"
                   : use_alone
                       ? "; what remains is better explained without it: " + d.proposal->equation
                       : "; what remains, learnt on top of it: " + d.proposal->equation;
    }
  } else if (tip_left || force_left) {
    d.verdict = "unexplained";
    d.summary = "unexplained: no catalog effect explains the residual; " + figures;
    for (const char* ch : {"tip", "force"}) {
      if ((std::string(ch) == "tip" ? tip_left : force_left)) {
        const std::string w = WhereWords(d.where, ch);
        if (!w.empty()) d.summary += "; " + w;
      }
    }
    if (o.discover || o.learn) {
      d.proposal = propose(model, d.base, d.base_cv);
      if (d.proposal) {
        d.summary += "; proposed: " + d.proposal->equation;
      } else {
        d.summary += "; no term of the discovery library and no learnt shape explains it either";
        if (!d.learning.note.empty()) d.summary += " (" + d.learning.note + ")";
      }
    }
  } else {
    d.verdict = "adequate";
    d.summary = "adequate: the held-out residual is at the noise floor in both channels (" +
                figures + ") and no variable explains a significant part of it";
  }
  if (d.proposal) {
    WriteProposal(*d.proposal, o);
    if (!d.learning.note.empty() && !d.learning.proposed.empty())
      d.summary += " (" + d.learning.note + ")";
  }
  d.adequate = d.verdict == "adequate";
  return d;
}

std::vector<LadderStep> ErrorLadder(const std::vector<std::string>& model, const LabDataset& ds,
                                    const DiagnoseOptions& o, int max_rounds) {
  std::vector<LadderStep> ladder;
  std::vector<std::string> current = model;
  DiagnoseOptions step_options = o;  // discovery runs only where the catalog ends (unexplained)
  for (int round = 0; round <= max_rounds; ++round) {
    LadderStep step;
    step.model = current;
    step.diagnosis = Diagnose(current, ds, step_options);
    const Diagnosis& d = step.diagnosis;
    const bool climb = d.verdict == "missing_effect" && round < max_rounds;
    const Candidate next = climb ? d.candidates.front() : Candidate{};
    ladder.push_back(std::move(step));
    if (!climb) break;
    std::erase(current, next.replaces);
    std::erase(step_options.swappable, next.replaces);
    current.push_back(next.effect);
    current = hw::ParseModelSpec(hw::FormatModelSpec(current), FitCatalog(o.fit));
    // What the ladder added may later be replaced by a better candidate.
    step_options.swappable.push_back(next.effect);
  }
  return ladder;
}

}  // namespace echoservo::lab
