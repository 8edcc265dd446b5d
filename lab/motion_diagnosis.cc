#include "lab/motion_diagnosis.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>

namespace echoservo::lab {
namespace {

constexpr int kPhaseBins = 8;
constexpr int kTimeSegments = 6;
constexpr int kPairPhaseBins = 8;
constexpr int kPairTimeBins = 4;

struct Sums {
  std::size_t n = 0;
  double ss = 0.0;
};

std::vector<MotionGroup> Groups(const std::vector<Sums>& sums,
                                const std::vector<std::string>& labels) {
  Sums total;
  for (const Sums& s : sums) {
    total.n += s.n;
    total.ss += s.ss;
  }
  std::vector<MotionGroup> out;
  for (std::size_t g = 0; g < sums.size(); ++g) {
    if (sums[g].n == 0) continue;
    const auto n = static_cast<double>(sums[g].n);
    out.push_back({labels[g], sums[g].n, std::sqrt(sums[g].ss / n),
                   n / static_cast<double>(total.n), total.ss > 0.0 ? sums[g].ss / total.ss : 0.0});
  }
  return out;
}

// The group holding a share of the squared residual well above its share of samples.
std::string Concentration(const std::vector<MotionGroup>& groups, const std::string& what) {
  const MotionGroup* best = nullptr;
  for (const MotionGroup& g : groups) {
    if (g.error_share >= 0.2 && g.error_share > 1.5 * g.sample_share &&
        (best == nullptr ||
         g.error_share / g.sample_share > best->error_share / best->sample_share)) {
      best = &g;
    }
  }
  if (best == nullptr) return "";
  return "residual concentrated in " + what + " " + best->label + " (" +
         PercentText(best->error_share) + " of the squared error in " +
         PercentText(best->sample_share) + " of the samples)";
}

std::vector<std::size_t> Indices(const estimation::MotionTrace& trace,
                                 const std::vector<std::size_t>& blocks, double block_s) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < trace.size(); ++i) {
    const auto b = static_cast<std::size_t>((trace.t_s[i] - trace.t_s.front()) / block_s);
    if (std::binary_search(blocks.begin(), blocks.end(), b)) out.push_back(i);
  }
  return out;
}

// Fits `spec` started from `start` and afresh; keeps the better (a drifting rate or a
// respiration rate can trap one start).
MotionFit FitBest(const MotionModelSpec& spec, const estimation::MotionTrace& trace, double noise,
                  const std::vector<double>& start) {
  MotionFit a = FitMotionModel(spec, trace, noise, {}, &start);
  MotionFit b = FitMotionModel(spec, trace, noise);
  return a.mse_norm <= b.mse_norm ? a : b;
}

}  // namespace

MotionBreakdown ComputeMotionBreakdown(const estimation::MotionTrace& trace, const MotionFit& fit) {
  std::vector<Sums> phase(kPhaseBins);
  std::vector<Sums> time(kTimeSegments);
  for (std::size_t i = 0; i < trace.size(); ++i) {
    const double e2 = std::pow(fit.prediction_mm[i] - trace.position_mm[i], 2);
    const auto p = std::min(
        kPhaseBins - 1, static_cast<int>(fit.phase_rad[i] / (2.0 * std::numbers::pi) * kPhaseBins));
    const auto s = std::min(kTimeSegments - 1,
                            static_cast<int>((trace.t_s[i] - trace.t_s.front()) /
                                             std::max(trace.duration_s(), 1e-9) * kTimeSegments));
    phase[static_cast<std::size_t>(p)].n += 1;
    phase[static_cast<std::size_t>(p)].ss += e2;
    time[static_cast<std::size_t>(s)].n += 1;
    time[static_cast<std::size_t>(s)].ss += e2;
  }
  std::vector<std::string> phase_labels;
  for (int b = 0; b < kPhaseBins; ++b) {
    phase_labels.push_back(std::to_string(b * 360 / kPhaseBins) + "-" +
                           std::to_string((b + 1) * 360 / kPhaseBins) + " deg");
  }
  std::vector<std::string> time_labels;
  const double seg = trace.duration_s() / kTimeSegments;
  for (int s = 0; s < kTimeSegments; ++s) {
    time_labels.push_back(FixedText(trace.t_s.front() + s * seg, 1) + "-" +
                          FixedText(trace.t_s.front() + (s + 1) * seg, 1) + " s");
  }
  return {Groups(phase, phase_labels), Groups(time, time_labels)};
}

MotionHeldOut HeldOutMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                            double noise, const MotionDiagnoseOptions& o,
                            const std::vector<double>* initial) {
  MotionHeldOut h;
  h.residual.assign(trace.size(), 0.0);
  h.fold.assign(trace.size(), 0);
  const auto blocks = static_cast<std::size_t>(trace.duration_s() / o.block_s) + 1;
  std::vector<std::pair<std::vector<std::size_t>, std::vector<std::size_t>>> folds;
  if (blocks < 2 || o.folds < 2) {
    // No held-out data: in-sample residuals, one fold.
    const MotionFit fit = FitMotionModel(spec, trace, noise, {}, initial);
    for (std::size_t i = 0; i < trace.size(); ++i)
      h.residual[i] = (fit.prediction_mm[i] - trace.position_mm[i]) / noise;
    h.mse = fit.mse_norm;
    return h;
  }
  // As CrossValidateFolds: block b is in fold b mod k.
  const auto k = std::min<std::size_t>(static_cast<std::size_t>(o.folds), blocks);
  double ss = 0.0;
  for (std::size_t f = 0; f < k; ++f) {
    std::vector<std::size_t> train;
    std::vector<std::size_t> test;
    for (std::size_t b = 0; b < blocks; ++b) (b % k == f ? test : train).push_back(b);
    const std::vector<std::size_t> test_index = Indices(trace, test, o.block_s);
    if (test_index.empty()) continue;
    const MotionFit fit =
        FitMotionModel(spec, trace, noise, Indices(trace, train, o.block_s), initial);
    for (std::size_t i : test_index) {
      h.residual[i] = (fit.prediction_mm[i] - trace.position_mm[i]) / noise;
      h.fold[i] = static_cast<int>(f);
      ss += h.residual[i] * h.residual[i];
    }
  }
  h.mse = ss / static_cast<double>(trace.size());
  return h;
}

double CrossValidateMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                           double noise, const MotionDiagnoseOptions& o,
                           const std::vector<double>* initial) {
  return HeldOutMotion(spec, trace, noise, o, initial).mse;
}

std::vector<WhereEntry> MotionWhere(const estimation::MotionTrace& trace, const MotionFit& fit,
                                    const MotionHeldOut& h, const MotionNoise& noise,
                                    double block_s) {
  const double excess = h.mse - 1.0;
  const double duration = std::max(trace.duration_s(), 1e-9);
  std::vector<double> time(trace.size());
  std::vector<int> phase_x_time(trace.size());
  for (std::size_t i = 0; i < trace.size(); ++i) {
    time[i] = trace.t_s[i] - trace.t_s.front();
    const int p =
        std::min(kPairPhaseBins - 1,
                 static_cast<int>(fit.phase_rad[i] / (2.0 * std::numbers::pi) * kPairPhaseBins));
    const int s = std::min(kPairTimeBins - 1, static_cast<int>(time[i] / duration * kPairTimeBins));
    phase_x_time[i] = p * kPairTimeBins + s;
  }
  // Time bins at least three CV blocks wide, so that a held-out block's bin has training data.
  StructureOptions time_options;
  time_options.bins = std::clamp(static_cast<int>(duration / (3.0 * block_s)), 2, 12);
  StructureOptions phase_options;
  phase_options.bins = 12;
  StructureOptions rate_options;
  rate_options.bins = 8;
  std::vector<WhereEntry> out = {
      {"position", "time_s", ExplainedByVariable(h.residual, time, h.fold, time_options), 0.0},
      {"position", "cardiac_phase",
       ExplainedByVariable(h.residual, fit.phase_rad, h.fold, phase_options), 0.0},
      {"position", "heart_rate_bpm",
       ExplainedByVariable(h.residual, noise.local_rate_bpm, h.fold, rate_options), 0.0},
      {"position", "cardiac_phase_x_time", ExplainedByBins(h.residual, phase_x_time, h.fold), 0.0},
  };
  for (WhereEntry& e : out) {
    e.explained_fraction =
        excess > 0.0 ? std::clamp(e.gain / excess, 0.0, 1.0) : (e.gain > 0.0 ? 1.0 : 0.0);
  }
  RankWhere(out);
  return out;
}

namespace {

std::string WhereText(const std::vector<WhereEntry>& where, double min_gain) {
  std::string text;
  for (const WhereEntry& e : where) {
    if (e.gain < min_gain) continue;
    text += (text.empty() ? "" : ", ") + e.variable + " (explains " +
            PercentText(e.explained_fraction) + " of the excess)";
  }
  return text;
}

// The default proposal folder: "<trace stem>_proposal" beside the trace.
std::filesystem::path ProposalDir(const estimation::MotionTrace& trace, const std::string& dir) {
  if (!dir.empty()) return dir;
  const std::filesystem::path source(trace.source.empty() ? "trace" : trace.source);
  return source.parent_path() / (source.stem().string() + "_proposal");
}

std::optional<MotionProposal> Discover(const MotionModelSpec& spec,
                                       const estimation::MotionTrace& trace, double noise,
                                       const MotionFit& base, double base_cv,
                                       const std::vector<WhereEntry>& where,
                                       const MotionDiagnoseOptions& o) {
  const std::vector<MotionTerm> library = MotionTermLibrary(spec.harmonics);
  std::vector<bool> used(library.size(), false);
  std::vector<MotionTerm> chosen;
  MotionModelSpec current = spec;
  MotionFit fit = base;
  double cv = base_cv;
  for (int round = 0; round < o.max_terms; ++round) {
    std::vector<std::size_t> open;
    for (std::size_t j = 0; j < library.size(); ++j)
      if (!used[j]) open.push_back(j);
    if (open.empty()) break;
    std::vector<double> scores(open.size(), std::numeric_limits<double>::infinity());
    ForEachInParallel(open.size(), o.threads, [&](std::size_t i) {
      MotionModelSpec with = current;
      with.terms.push_back(library[open[i]]);
      const std::vector<double> start = StartMotionParameters(with, fit, trace);
      scores[i] = CrossValidateMotion(with, trace, noise, o, &start);
    });
    const auto best =
        static_cast<std::size_t>(std::min_element(scores.begin(), scores.end()) - scores.begin());
    if (!(cv - scores[best] >= o.min_discovery_gain)) break;
    used[open[best]] = true;
    chosen.push_back(library[open[best]]);
    current.terms.push_back(library[open[best]]);
    const std::vector<double> start = StartMotionParameters(current, fit, trace);
    fit = FitMotionModel(current, trace, noise, {}, &start);
    cv = scores[best];
  }
  if (chosen.empty()) return std::nullopt;
  MotionProposal p;
  for (const MotionTerm& t : chosen) {
    p.terms.push_back(t.name);
    p.equation += (p.equation.empty() ? "position_mm += " : " + ") + t.equation;
  }
  const std::filesystem::path file = ProposalDir(trace, o.propose_dir) / "motion_term.json";
  std::string signature = "held-out residual of " + FormatMotionModel(spec);
  if (!where.empty()) signature += " structured along " + where.front().variable;
  WriteMotionTermFile(file, "motion_term", signature, chosen);
  p.file = file.string();
  p.spec = FormatMotionModel(spec) + "+@" + p.file;
  // Refit from the file as a user would: the SPEC is parsed and the file read back.
  const MotionModelSpec from_file = ParseMotionModel(p.spec);
  p.fit = FitMotionModel(from_file, trace, noise, {}, &fit.parameters);
  p.cv_mse = CrossValidateMotion(from_file, trace, noise, o, &p.fit.parameters);
  p.rms_mm = std::sqrt(p.cv_mse) * noise;
  return p;
}

}  // namespace

MotionDiagnosis DiagnoseMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                               const MotionDiagnoseOptions& o) {
  MotionDiagnosis d;
  d.model = spec;
  d.noise = EstimateMotionNoise(trace);
  d.noise_mm = d.noise.position_mm;
  d.base = FitMotionModel(spec, trace, d.noise_mm);
  const MotionHeldOut held = HeldOutMotion(spec, trace, d.noise_mm, o, &d.base.parameters);
  d.base_cv_mse = held.mse;
  d.excess = held.mse - 1.0;
  d.held_out_rms_mm = std::sqrt(held.mse) * d.noise_mm;
  d.breakdown = ComputeMotionBreakdown(trace, d.base);
  d.where = MotionWhere(trace, d.base, held, d.noise, o.block_s);
  const std::vector<std::string> names = MissingMotionEffects(spec);
  d.candidates.resize(names.size());
  ForEachInParallel(names.size(), o.threads, [&](std::size_t i) {
    MotionCandidate& c = d.candidates[i];
    c.effect = names[i];
    const MotionModelSpec with = WithMotionEffect(spec, names[i]);
    c.fit = FitBest(with, trace, d.noise_mm, StartMotionParameters(with, d.base, trace));
    c.cv_mse = CrossValidateMotion(with, trace, d.noise_mm, o, &c.fit.parameters);
  });
  for (MotionCandidate& c : d.candidates) {
    const Judgement j = JudgeCandidate({d.base_cv_mse}, {c.cv_mse}, o.rule);
    c.explained = j.explained.front();
    c.score = j.score;
    c.significant = j.significant;
  }
  RankCandidates(d.candidates);
  for (MotionCandidate& c : d.candidates) {
    std::string text =
        "position RMS " + FixedText(d.base.rms_mm, 4) + " mm -> " + FixedText(c.fit.rms_mm, 4) +
        " mm (" +
        PercentText(d.base.rms_mm > 0.0 ? (c.fit.rms_mm - d.base.rms_mm) / d.base.rms_mm : 0.0) +
        ")";
    text += std::isfinite(c.explained)
                ? "; explains " + PercentText(c.explained) + " of the held-out excess residual"
                : "; the model leaves no excess over the noise";
    if (c.significant) {
      for (const std::string& s : {Concentration(d.breakdown.cardiac_phase, "cardiac phase"),
                                   Concentration(d.breakdown.time, "time")}) {
        if (!s.empty()) text += "; " + s;
      }
      text += "; expected signature: " + MotionEffectSignature(c.effect);
    }
    c.evidence = text;
  }
  const std::string size = "held-out RMS " + FixedText(d.held_out_rms_mm, 4) +
                           " mm against noise " + FixedText(d.noise_mm, 4) + " mm (excess " +
                           FixedText(d.excess, 2) + " noise variances)";
  const std::string structure = WhereText(d.where, o.min_structure_gain);
  if (!d.candidates.empty() && d.candidates.front().significant) {
    d.verdict = "missing_effect";
    d.summary = "missing effect: " + d.candidates.front().effect + " (" +
                d.candidates.front().evidence + ")";
  } else if (d.excess >= o.rule.min_excess || !structure.empty()) {
    d.verdict = "unexplained";
    d.summary = "unexplained: " + size + "; no catalog effect explains it; ";
    d.summary += structure.empty() ? "no structure along time, cardiac phase or heart rate"
                                   : "it lies along " + structure;
    if (o.discover) {
      d.proposal = Discover(spec, trace, d.noise_mm, d.base, d.base_cv_mse, d.where, o);
      d.summary += d.proposal
                       ? "; proposed term: " + d.proposal->equation + " (" + d.proposal->spec +
                             ": held-out RMS " + FixedText(d.proposal->rms_mm, 4) + " mm)"
                       : "; no library term removes it";
    }
  } else {
    d.verdict = "adequate";
    d.summary = "adequate: " + size +
                "; no catalog effect explains a significant part of it "
                "and the held-out residual has no structure along time, cardiac phase or heart "
                "rate";
  }
  d.adequate = d.verdict == "adequate";
  return d;
}

}  // namespace echoservo::lab
