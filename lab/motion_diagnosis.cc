#include "lab/motion_diagnosis.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>
#include <utility>

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

// Discovery and learned shapes (a named namespace: the lab is built in unity batches).
namespace motion_discovery {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

double MedianStep(const estimation::MotionTrace& trace) {
  std::vector<double> d;
  for (std::size_t i = 1; i < trace.size(); ++i) d.push_back(trace.t_s[i] - trace.t_s[i - 1]);
  if (d.empty()) return 0.04;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

// The fitted heartbeat's harmonics (estimates cos<k>, sin<k>).
struct Heartbeat {
  std::vector<double> a;
  std::vector<double> b;
  double At(double phase) const {
    double h = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) {
      const double kp = static_cast<double>(k + 1) * phase;
      h += a[k] * std::cos(kp) + b[k] * std::sin(kp);
    }
    return h;
  }
  // RMS of dH/dφ over a cycle (mm/rad).
  double SlopeRms() const {
    double ss = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k)
      ss += static_cast<double>((k + 1) * (k + 1)) * (a[k] * a[k] + b[k] * b[k]) / 2.0;
    return std::sqrt(ss);
  }
};

Heartbeat HeartbeatOf(const MotionFit& fit) {
  Heartbeat h;
  for (int k = 1; k <= fit.spec.harmonics; ++k) {
    double a = 0.0;
    double b = 0.0;
    for (const ParameterEstimate& e : fit.estimates) {
      if (e.name == "cos" + std::to_string(k)) a = e.value;
      if (e.name == "sin" + std::to_string(k)) b = e.value;
    }
    h.a.push_back(a);
    h.b.push_back(b);
  }
  return h;
}

// A sinusoid of period `period_s` found in a residual: y ≈ nuisance + carrier·(c cos + s sin).
struct Peak {
  double period_s = 0.0;
  double c = 0.0;
  double s = 0.0;
  double gain = 0.0;             // sum of squares removed beyond the nuisance columns
  std::vector<double> nuisance;  // coefficients of 1 (and t)
};

// Least squares of y on carrier·cos(2πt/T), carrier·sin(2πt/T) and the nuisance columns 1
// (and t when `trend`), for periods in [shortest, longest] on a fine frequency grid: the
// `count` largest local maxima of the sum of squares removed.
std::vector<Peak> Spectrum(const std::vector<double>& t, const std::vector<double>& y,
                           const std::vector<double>* carrier, bool trend, double shortest,
                           double longest, double duration, int count) {
  const int m = trend ? 2 : 1;
  const auto n = t.size();
  const auto solve = [&](int columns, const auto& column) {
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(columns, columns);
    Eigen::VectorXd r = Eigen::VectorXd::Zero(columns);
    Eigen::VectorXd x(columns);
    for (std::size_t i = 0; i < n; ++i) {
      for (int j = 0; j < columns; ++j) x[j] = column(i, j);
      a.noalias() += x * x.transpose();
      r += x * y[i];
    }
    Eigen::VectorXd beta = a.ldlt().solve(r);
    return std::make_pair(beta, beta.dot(r));  // sum of squares explained
  };
  const auto nuisance = [&](std::size_t i, int j) { return j == 0 ? 1.0 : t[i]; };
  const double floor = solve(m, nuisance).second;
  std::vector<Peak> grid;
  const double df = 0.05 / std::max(duration, 1.0);
  for (double f = 1.0 / longest; f <= 1.0 / shortest; f += df) {
    const auto [beta, explained] = solve(m + 2, [&](std::size_t i, int j) {
      if (j < m) return nuisance(i, j);
      const double w = kTwoPi * f * t[i];
      const double g = carrier != nullptr ? (*carrier)[i] : 1.0;
      return g * (j == m ? std::cos(w) : std::sin(w));
    });
    Peak p;
    p.period_s = 1.0 / f;
    p.c = beta[m];
    p.s = beta[m + 1];
    p.gain = explained - floor;
    for (int j = 0; j < m; ++j) p.nuisance.push_back(beta[j]);
    if (std::isfinite(p.gain)) grid.push_back(p);
  }
  std::vector<Peak> peaks;
  for (std::size_t i = 0; i < grid.size(); ++i) {
    if ((i == 0 || grid[i].gain >= grid[i - 1].gain) &&
        (i + 1 == grid.size() || grid[i].gain >= grid[i + 1].gain))
      peaks.push_back(grid[i]);
  }
  std::sort(peaks.begin(), peaks.end(),
            [](const Peak& a, const Peak& b) { return a.gain > b.gain; });
  if (peaks.size() > static_cast<std::size_t>(count)) peaks.resize(static_cast<std::size_t>(count));
  return peaks;
}

// The beats' phase offset δ (rad, unwrapped) against the fit's phase, from windows of 1.5
// beats: the δ that best aligns the fitted heartbeat with the measured beats there.
struct LocalPhase {
  std::vector<double> t;
  std::vector<double> delta;
};

LocalPhase LocalPhaseOffsets(const estimation::MotionTrace& trace, const MotionFit& fit,
                             const Heartbeat& hb, double rate_hz) {
  LocalPhase out;
  const double half = 0.75 / rate_hz;
  constexpr int kGrid = 72;
  std::vector<double> time(trace.size());
  std::vector<double> y(trace.size());
  for (std::size_t i = 0; i < trace.size(); ++i) {
    time[i] = trace.t_s[i] - trace.t_s.front();
    // Measured less every part of the model but the heartbeat.
    y[i] = trace.position_mm[i] - (fit.prediction_mm[i] - fit.heartbeat_mm[i]);
  }
  const double end = time.back();
  for (double c = half; c <= end - half + 1e-9; c += 0.25) {
    const auto lo = static_cast<std::size_t>(std::lower_bound(time.begin(), time.end(), c - half) -
                                             time.begin());
    const auto hi = static_cast<std::size_t>(std::upper_bound(time.begin(), time.end(), c + half) -
                                             time.begin());
    if (hi < lo + 8) continue;
    std::vector<double> sse(kGrid);
    for (int g = 0; g < kGrid; ++g) {
      const double d = kTwoPi * g / kGrid - std::numbers::pi;
      double sr = 0.0;
      double sr2 = 0.0;
      for (std::size_t i = lo; i < hi; ++i) {
        const double r = y[i] - hb.At(fit.phase_rad[i] + d);
        sr += r;
        sr2 += r * r;
      }
      sse[static_cast<std::size_t>(g)] = sr2 - sr * sr / static_cast<double>(hi - lo);
    }
    const auto best = static_cast<int>(std::min_element(sse.begin(), sse.end()) - sse.begin());
    const double l = sse[static_cast<std::size_t>((best + kGrid - 1) % kGrid)];
    const double m = sse[static_cast<std::size_t>(best)];
    const double r = sse[static_cast<std::size_t>((best + 1) % kGrid)];
    const double curvature = l - 2.0 * m + r;
    const double shift = curvature > 0.0 ? std::clamp(0.5 * (l - r) / curvature, -0.5, 0.5) : 0.0;
    double d = kTwoPi * (best + shift) / kGrid - std::numbers::pi;
    if (!out.delta.empty()) d += kTwoPi * std::round((out.delta.back() - d) / kTwoPi);
    out.t.push_back(c);
    out.delta.push_back(d);
  }
  return out;
}

struct Jump {
  double t_s = 0.0;
  double size_mm = 0.0;
};

// The largest jumps of e (mean over the next `w` s minus mean over the last `w` s), at
// least 2w apart.
std::vector<Jump> Jumps(const std::vector<double>& time, const std::vector<double>& e, double w,
                        int count) {
  std::vector<double> sum(e.size() + 1, 0.0);
  for (std::size_t i = 0; i < e.size(); ++i) sum[i + 1] = sum[i] + e[i];
  std::vector<Jump> all;
  for (std::size_t i = 1; i < e.size(); ++i) {
    const auto lo = static_cast<std::size_t>(
        std::lower_bound(time.begin(), time.end(), time[i] - w) - time.begin());
    const auto hi = static_cast<std::size_t>(
        std::lower_bound(time.begin(), time.end(), time[i] + w) - time.begin());
    if (i < lo + 3 || hi < i + 3) continue;
    const double left = (sum[i] - sum[lo]) / static_cast<double>(i - lo);
    const double right = (sum[hi] - sum[i]) / static_cast<double>(hi - i);
    all.push_back({0.5 * (time[i - 1] + time[i]), right - left});
  }
  std::sort(all.begin(), all.end(),
            [](const Jump& a, const Jump& b) { return std::abs(a.size_mm) > std::abs(b.size_mm); });
  std::vector<Jump> out;
  for (const Jump& j : all) {
    if (out.size() >= static_cast<std::size_t>(count)) break;
    if (std::all_of(out.begin(), out.end(),
                    [&](const Jump& o) { return std::abs(o.t_s - j.t_s) >= 2.0 * w; }))
      out.push_back(j);
  }
  return out;
}

// What the current fit's residual says about where a new term should start.
struct Clues {
  std::vector<Jump> jumps;
  std::vector<Peak> baseline;    // slow sinusoids of the residual
  std::vector<Peak> modulation;  // of the residual against the heartbeat
  std::vector<Peak> rate;        // of the beats' local phase offset (nuisance 1, t)
  LocalPhase phase;
};

Clues FindClues(const estimation::MotionTrace& trace, const MotionFit& fit,
                const MotionTermContext& context, const std::vector<MotionTerm>& library) {
  Clues c;
  std::vector<double> time(trace.size());
  std::vector<double> e(trace.size());
  for (std::size_t i = 0; i < trace.size(); ++i) {
    time[i] = trace.t_s[i] - trace.t_s.front();
    e[i] = trace.position_mm[i] - fit.prediction_mm[i];
  }
  const auto period_bounds = [&](MotionTermKind kind) {
    for (const MotionTerm& t : library) {
      if (t.kind == kind) return std::make_pair(t.lower.back(), t.upper.back());
    }
    return std::make_pair(1.0, 2.0 * context.duration_s);
  };
  c.jumps = Jumps(time, e, std::max(1.0 / context.rate_hz, 0.5), 2);
  const auto [sine_lo, sine_hi] = period_bounds(MotionTermKind::kBaselineSine);
  c.baseline = Spectrum(time, e, nullptr, false, sine_lo, sine_hi, context.duration_s, 3);
  const auto [am_lo, am_hi] = period_bounds(MotionTermKind::kAmplitudeModulation);
  c.modulation = Spectrum(time, e, &fit.heartbeat_mm, false, am_lo, am_hi, context.duration_s, 3);
  c.phase = LocalPhaseOffsets(trace, fit, HeartbeatOf(fit), context.rate_hz);
  if (c.phase.t.size() >= 8) {
    const auto [rate_lo, rate_hi] = period_bounds(MotionTermKind::kRateModulation);
    c.rate =
        Spectrum(c.phase.t, c.phase.delta, nullptr, true, rate_lo, rate_hi, context.duration_s, 3);
  }
  return c;
}

// The index of the first parameter of the spec's terms (they come last in the vector).
std::size_t FirstTermParameter(const MotionModelSpec& spec, std::size_t size) {
  std::size_t n = 0;
  for (const MotionTerm& t : spec.terms) n += t.parameters.size();
  return size - n;
}

// Starting vectors for `with` (= the current spec + one library term, last) from the current
// fit and the clues.
std::vector<std::vector<double>> TermStarts(const MotionModelSpec& with, const MotionFit& fit,
                                            const estimation::MotionTrace& trace,
                                            const Clues& clues) {
  const std::vector<double> base = StartMotionParameters(with, fit, trace);
  const MotionTerm& term = with.terms.back();
  const std::size_t at = base.size() - term.parameters.size();
  std::vector<std::vector<double>> out = {base};
  const auto add = [&](std::initializer_list<double> values) {
    std::vector<double> p = base;
    std::size_t k = at;
    for (double v : values) p[k++] = v;
    out.push_back(p);
  };
  switch (term.kind) {
    case MotionTermKind::kBaselineStep:
      out.clear();
      for (const Jump& j : clues.jumps) add({j.size_mm, j.t_s, std::max(0.25, term.lower[2])});
      if (out.empty()) out.push_back(base);
      break;
    case MotionTermKind::kBaselineSine:
      for (const Peak& p : clues.baseline) add({p.c, p.s, p.period_s});
      break;
    case MotionTermKind::kAmplitudeModulation:
      for (const Peak& p : clues.modulation) add({p.c, p.s, p.period_s});
      break;
    case MotionTermKind::kRateModulation:
      // δφ = A cos + B sin is T·(r_c sin − r_s cos): r_c = B/T, r_s = −A/T; its trend is
      // a rate offset.
      for (const Peak& p : clues.rate) {
        add({p.s / p.period_s, -p.c / p.period_s, p.period_s});
        out.back()[1] += p.nuisance.at(1) / kTwoPi;
      }
      break;
    case MotionTermKind::kBeatTiming: {
      const LocalPhase& lp = clues.phase;
      if (lp.t.size() < 2) break;
      std::vector<double> knots;
      for (std::size_t j = 0; j < term.parameters.size(); ++j) {
        const double t = static_cast<double>(j) * term.knot_spacing_s;
        const auto k = std::clamp<std::size_t>(
            static_cast<std::size_t>(std::lower_bound(lp.t.begin(), lp.t.end(), t) - lp.t.begin()),
            1, lp.t.size() - 1);
        const double f = std::clamp((t - lp.t[k - 1]) / (lp.t[k] - lp.t[k - 1]), 0.0, 1.0);
        knots.push_back(lp.delta[k - 1] * (1.0 - f) + lp.delta[k] * f);
      }
      // Without its mean and trend (the harmonics and the rate hold those).
      double st = 0, sd = 0, stt = 0, std_ = 0;
      const auto n = static_cast<double>(knots.size());
      for (std::size_t j = 0; j < knots.size(); ++j) {
        const double t = static_cast<double>(j) * term.knot_spacing_s;
        st += t;
        sd += knots[j];
        stt += t * t;
        std_ += t * knots[j];
      }
      const double det = n * stt - st * st;
      const double slope = det > 0.0 ? (n * std_ - st * sd) / det : 0.0;
      const double mean = (sd - slope * st) / n;
      std::vector<double> p = base;
      for (std::size_t j = 0; j < knots.size(); ++j)
        p[at + j] = knots[j] - mean - slope * static_cast<double>(j) * term.knot_spacing_s;
      p[1] += slope / kTwoPi;
      out.push_back(p);
      break;
    }
    default:
      break;
  }
  return out;
}

// `p` with every beat_timing term's knots at 0: a fold restarts them, so that knots only
// the held-out samples see are not carried over from the fit to every sample.
std::vector<double> WithoutLocalKnots(const std::vector<MotionTermKind>& kinds,
                                      const std::vector<std::size_t>& sizes, std::size_t first,
                                      std::vector<double> p) {
  std::size_t at = first;
  for (std::size_t j = 0; j < kinds.size(); ++j) {
    if (kinds[j] == MotionTermKind::kBeatTiming)
      std::fill(p.begin() + static_cast<std::ptrdiff_t>(at),
                p.begin() + static_cast<std::ptrdiff_t>(at + sizes[j]), 0.0);
    at += sizes[j];
  }
  return p;
}

std::vector<double> WithoutLocalKnots(const MotionModelSpec& spec, std::vector<double> p) {
  std::vector<MotionTermKind> kinds;
  std::vector<std::size_t> sizes;
  for (const MotionTerm& t : spec.terms) {
    kinds.push_back(t.kind);
    sizes.push_back(t.parameters.size());
  }
  const std::size_t first = FirstTermParameter(spec, p.size());
  return WithoutLocalKnots(kinds, sizes, first, std::move(p));
}

struct Trial {
  MotionFit fit;
  double cv = std::numeric_limits<double>::infinity();
};

std::optional<MotionProposal> Discover(const MotionModelSpec& spec,
                                       const estimation::MotionTrace& trace, double noise,
                                       const MotionFit& base, double base_cv,
                                       const std::vector<WhereEntry>& where,
                                       const MotionDiagnoseOptions& o) {
  MotionTermContext context;
  context.duration_s = trace.duration_s();
  context.sample_period_s = MedianStep(trace);
  context.rate_hz = base.parameters.at(1);
  std::vector<MotionTerm> library = MotionTermLibrary(spec.harmonics, context);
  const double slope = HeartbeatOf(base).SlopeRms();
  for (MotionTerm& t : library) {
    if (t.kind != MotionTermKind::kBeatTiming) continue;
    // About one knot's worth of data against its curvature.
    const double per_knot = t.knot_spacing_s / context.sample_period_s;
    const double weight = std::sqrt(per_knot) * slope / noise;
    if (std::isfinite(weight) && weight > 0.0) t.penalty = weight;
  }
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
    const Clues clues = FindClues(trace, fit, context, library);
    std::vector<Trial> trials(open.size());
    ForEachInParallel(open.size(), o.threads, [&](std::size_t i) {
      MotionModelSpec with = current;
      with.terms.push_back(library[open[i]]);
      Trial& trial = trials[i];
      bool first = true;
      for (const std::vector<double>& start : TermStarts(with, fit, trace, clues)) {
        MotionFit f = FitMotionModel(with, trace, noise, {}, &start);
        if (first || f.mse_norm < trial.fit.mse_norm) trial.fit = std::move(f);
        first = false;
      }
      const std::vector<double> start = WithoutLocalKnots(with, trial.fit.parameters);
      trial.cv = CrossValidateMotion(with, trace, noise, o, &start);
    });
    std::size_t best = 0;
    for (std::size_t i = 1; i < trials.size(); ++i)
      if (trials[i].cv < trials[best].cv) best = i;
    if (!(cv - trials[best].cv >= o.min_discovery_gain)) break;
    used[open[best]] = true;
    chosen.push_back(library[open[best]]);
    current.terms.push_back(library[open[best]]);
    fit = std::move(trials[best].fit);
    cv = trials[best].cv;
  }
  if (chosen.empty()) return std::nullopt;
  MotionProposal p;
  // The file's defaults are the fitted values: a user's refit starts there.
  std::size_t at = FirstTermParameter(current, fit.parameters.size());
  std::vector<MotionTermKind> kinds;
  std::vector<std::size_t> sizes;
  for (MotionTerm& t : chosen) {
    p.terms.push_back(t.name);
    p.equation += (p.equation.empty() ? "position_mm += " : " + ") + t.equation;
    for (std::size_t q = 0; q < t.parameters.size(); ++q)
      t.start[q] = std::clamp(fit.parameters[at + q], t.lower[q], t.upper[q]);
    at += t.parameters.size();
    kinds.push_back(t.kind);
    sizes.push_back(t.parameters.size());
  }
  const std::filesystem::path file = ProposalDir(trace, o.propose_dir) / "motion_term.json";
  std::string signature = "held-out residual of " + FormatMotionModel(spec);
  if (!where.empty()) signature += " structured along " + where.front().variable;
  WriteMotionTermFile(file, "motion_term", signature, chosen);
  p.file = file.string();
  p.spec = FormatMotionModel(spec) + "+@" + p.file;
  // Refit from the file as a user would: the SPEC is parsed and the file read back.
  MotionModelSpec from_file = ParseMotionModel(p.spec);
  // beat_timing's knots keep the penalty they were selected with (the file cannot carry it).
  std::size_t within = 0;
  for (const MotionTerm& t : chosen) {
    if (t.penalty > 0.0 && t.penalty_knots > 0 && !from_file.terms.empty()) {
      MotionTerm& f = from_file.terms.back();
      f.penalty = t.penalty;
      f.penalty_first = within + t.penalty_first;
      f.penalty_knots = t.penalty_knots;
    }
    within += t.parameters.size();
  }
  p.fit = FitMotionModel(from_file, trace, noise, {}, &fit.parameters);
  // The file term's parameters come last, the chosen terms' in order.
  std::size_t file_parameters = 0;
  for (std::size_t size : sizes) file_parameters += size;
  const std::vector<double> start =
      WithoutLocalKnots(kinds, sizes, p.fit.parameters.size() - file_parameters, p.fit.parameters);
  p.cv_mse = CrossValidateMotion(from_file, trace, noise, o, &start);
  p.rms_mm = std::sqrt(p.cv_mse) * noise;
  p.noise_ratio = p.rms_mm / noise;
  return p;
}

std::vector<double> Uniform(double lo, double hi, int count) {
  std::vector<double> out;
  for (int i = 0; i < count; ++i) out.push_back(lo + (hi - lo) * i / (count - 1));
  return out;
}

// The held-out residual learnt along each `where` variable (and the pair); lowest
// held-out mean square first.
std::vector<LearnedMotionShape> LearnShapes(const estimation::MotionTrace& trace,
                                            const MotionFit& base, const MotionHeldOut& held,
                                            const MotionNoise& noise,
                                            std::vector<std::vector<double>>* time_phase_rate) {
  const double sigma = noise.position_mm;
  const std::size_t n = trace.size();
  if (std::all_of(held.fold.begin(), held.fold.end(), [&](int f) { return f == held.fold[0]; }))
    return {};
  std::vector<double> time(n);
  for (std::size_t i = 0; i < n; ++i) time[i] = trace.t_s[i] - trace.t_s.front();
  std::vector<double> rate = noise.local_rate_bpm;
  if (rate.size() != n) rate.assign(n, 60.0 * noise.rate_hz);
  *time_phase_rate = {time, base.phase_rad, rate};
  ShapeSamples samples;
  for (std::size_t i = 0; i < n; ++i) samples.target.push_back(-held.residual[i] * sigma);
  samples.fold = held.fold;
  const double duration = std::max(trace.duration_s(), 1e-9);
  const int time_knots = std::clamp(static_cast<int>(duration / 1.0) + 1, 3, 61);
  const int pair_time_knots = std::clamp(static_cast<int>(duration / 4.0) + 1, 3, 9);
  struct Definition {
    std::string where;
    std::vector<std::string> variables;
    std::vector<std::string> units;
    std::vector<std::vector<double>> inputs;
    std::vector<std::vector<double>> knots;
  };
  const std::vector<Definition> definitions = {
      {"time_s", {"time_s"}, {"s"}, {time}, {Uniform(0.0, duration, time_knots)}},
      {"cardiac_phase",
       {"cardiac_phase_rad"},
       {"rad"},
       {base.phase_rad},
       {Uniform(0.0, kTwoPi, 13)}},
      {"heart_rate_bpm", {"heart_rate_bpm"}, {"bpm"}, {rate}, {QuantileKnots(rate, 8)}},
      {"cardiac_phase_x_time",
       {"cardiac_phase_rad", "time_s"},
       {"rad", "s"},
       {base.phase_rad, time},
       {Uniform(0.0, kTwoPi, 9), Uniform(0.0, duration, pair_time_knots)}},
  };
  std::vector<LearnedMotionShape> out;
  for (const Definition& d : definitions) {
    std::vector<ShapeAxis> axes;
    for (std::size_t a = 0; a < d.variables.size(); ++a)
      axes.push_back({d.variables[a], d.knots[a]});
    if (std::any_of(axes.begin(), axes.end(),
                    [](const ShapeAxis& a) { return a.knots.size() < 2; }))
      continue;
    samples.inputs = d.inputs;
    try {
      LearnedMotionShape s;
      s.where = d.where;
      s.variables = d.variables;
      s.units = d.units;
      s.shape = FitSmoothShape(axes, samples);
      s.held_out_mse = s.shape.held_out_mse / (sigma * sigma);
      s.gain = s.shape.held_out_gain / (sigma * sigma);
      out.push_back(std::move(s));
    } catch (const std::invalid_argument&) {
      // A variable without spread on this trace: no shape along it.
    }
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const LearnedMotionShape& a, const LearnedMotionShape& b) {
                     return a.held_out_mse < b.held_out_mse;
                   });
  return out;
}

// The Pareto front of formulas distilling `shape` (its values at the samples).
std::vector<Formula> DistilShape(const LearnedMotionShape& shape,
                                 const std::vector<std::vector<double>>& time_phase_rate,
                                 const std::vector<int>& fold) {
  FormulaData data;
  for (std::size_t a = 0; a < shape.variables.size(); ++a) {
    data.variables.push_back({shape.variables[a], shape.units[a]});
    const std::size_t which = shape.variables[a] == "time_s"              ? 0
                              : shape.variables[a] == "cardiac_phase_rad" ? 1
                                                                          : 2;
    data.inputs.push_back(time_phase_rate[which]);
  }
  const std::size_t n = fold.size();
  std::vector<double> in(data.inputs.size());
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t a = 0; a < in.size(); ++a) in[a] = data.inputs[a][i];
    data.target.push_back(shape.shape.Evaluate(in.data()));
  }
  data.fold = fold;
  data.target_unit = "mm";
  try {
    return ParetoFront(SearchFormulas(data));
  } catch (const std::invalid_argument&) {
    return {};
  }
}

}  // namespace motion_discovery

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
  // Learned shapes interpolate between time blocks where a binned mean cannot (a held-out
  // block's slow-time bin has no training data): where the smooth shape along a `where`
  // variable carries over to held-out blocks better, its gain is that variable's (a heart
  // rate swinging every 12 s shows along cardiac_phase_x_time only this way).
  std::vector<std::vector<double>> shape_inputs;
  if (o.learn_shapes && d.excess >= o.rule.min_excess) {
    d.shapes = motion_discovery::LearnShapes(trace, d.base, held, d.noise, &shape_inputs);
    for (const LearnedMotionShape& shape : d.shapes) {
      for (WhereEntry& e : d.where) {
        if (e.variable != shape.where || !(shape.gain > e.gain)) continue;
        e.gain = shape.gain;
        e.explained_fraction = d.excess >= 0.05 ? std::clamp(e.gain / d.excess, 0.0, 1.0) : 0.0;
      }
    }
    RankWhere(d.where);
  }
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
      d.proposal =
          motion_discovery::Discover(spec, trace, d.noise_mm, d.base, d.base_cv_mse, d.where, o);
      d.summary += d.proposal
                       ? "; proposed term: " + d.proposal->equation + " (" + d.proposal->spec +
                             ": held-out RMS " + FixedText(d.proposal->rms_mm, 4) + " mm, " +
                             FixedText(d.proposal->noise_ratio, 2) + "x the noise floor)"
                       : "; no library term removes it";
    }
    if (o.learn_shapes) {
      if (d.shapes.empty())
        d.shapes = motion_discovery::LearnShapes(trace, d.base, held, d.noise, &shape_inputs);
      if (!d.shapes.empty() && d.shapes.front().gain > 0.0) {
        const LearnedMotionShape& best = d.shapes.front();
        d.formulas = motion_discovery::DistilShape(best, shape_inputs, held.fold);
        d.summary += "; learned shape along " + best.where + ": held-out RMS " +
                     FixedText(std::sqrt(std::max(best.held_out_mse, 0.0)) * d.noise_mm, 4) + " mm";
        const auto most = std::min_element(
            d.formulas.begin(), d.formulas.end(),
            [](const Formula& a, const Formula& b) { return a.held_out_mse < b.held_out_mse; });
        if (most != d.formulas.end())
          d.summary += ", distilled as " + most->form + ": " + most->words;
      }
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
