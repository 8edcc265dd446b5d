#include "lab/motion_diagnosis.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "lab/lab_dataset.h"

namespace echoservo::lab {
namespace {

constexpr int kPhaseBins = 8;
constexpr int kTimeSegments = 6;

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

double MotionLabNoise(const MotionModelSpec& spec, const estimation::MotionTrace& trace) {
  MotionModelSpec rich = spec;
  rich.respiration = true;
  rich.rate_drift = true;
  rich.harmonics = std::min(spec.harmonics + 3, 12);
  const double rough = EstimateNoise(trace.position_mm, 1e-3);
  // The residual scale does not change where the fit ends, only its normalisation.
  const MotionFit base = FitMotionModel(spec, trace, rough);
  const MotionFit fit = FitBest(rich, trace, rough, StartMotionParameters(rich, base, trace));
  const int params = 2 + 1 + 3 + 2 * rich.harmonics;
  const double dof = std::max(1.0, static_cast<double>(trace.size()) - params);
  const double sigma = fit.rms_mm * std::sqrt(static_cast<double>(trace.size()) / dof);
  return std::max(std::min(rough, sigma), 1e-3);
}

double CrossValidateMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                           double noise, const MotionDiagnoseOptions& o,
                           const std::vector<double>* initial) {
  const auto blocks = static_cast<std::size_t>(trace.duration_s() / o.block_s) + 1;
  if (blocks < 2 || o.folds < 2) return FitMotionModel(spec, trace, noise, {}, initial).mse_norm;
  return CrossValidateFolds(
             blocks, o.folds,
             [&](const std::vector<std::size_t>& train, const std::vector<std::size_t>& test) {
               const std::vector<std::size_t> fit_index = Indices(trace, train, o.block_s);
               const std::vector<std::size_t> test_index = Indices(trace, test, o.block_s);
               const MotionFit fit = FitMotionModel(spec, trace, noise, fit_index, initial);
               return FoldScore{
                   {EvaluateMotionModel(spec, fit.parameters, trace, noise, test_index)},
                   static_cast<double>(test_index.size())};
             })
      .front();
}

MotionDiagnosis DiagnoseMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                               const MotionDiagnoseOptions& o) {
  MotionDiagnosis d;
  d.model = spec;
  d.noise_mm = MotionLabNoise(spec, trace);
  d.base = FitMotionModel(spec, trace, d.noise_mm);
  d.base_cv_mse = CrossValidateMotion(spec, trace, d.noise_mm, o, &d.base.parameters);
  d.breakdown = ComputeMotionBreakdown(trace, d.base);
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
  d.adequate = d.candidates.empty() || !d.candidates.front().significant;
  d.verdict = d.adequate ? "adequate: no catalog effect explains a significant part of the "
                           "residual (position RMS " +
                               FixedText(d.base.rms_mm, 4) + " mm against noise " +
                               FixedText(d.noise_mm, 4) + " mm)"
                         : "missing effect: " + d.candidates.front().effect + " (" +
                               d.candidates.front().evidence + ")";
  return d;
}

}  // namespace echoservo::lab
