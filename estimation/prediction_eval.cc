#include "estimation/prediction_eval.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

#include "estimation/harmonic_fit.h"

namespace echoservo::estimation {
namespace {

struct Accumulator {
  double ss = 0.0;
  double abs = 0.0;
  double max = 0.0;
  std::size_t n = 0;
  void Add(double e) {
    ss += e * e;
    abs += std::abs(e);
    max = std::max(max, std::abs(e));
    ++n;
  }
  PredictionScore Score(const std::string& name) const {
    const double dn = static_cast<double>(std::max<std::size_t>(n, 1));
    return {name, std::sqrt(ss / dn), abs / dn, max};
  }
};

// The constant-velocity KF's acceleration density from the first window: the mean
// square second difference over dt⁴ is the acceleration variance; q = that × dt (a
// white acceleration held over one interval), floored so the filter never freezes.
double CvAccelPsd(const MotionTrace& m, double window_s) {
  double ss = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 2; i < m.size() && m.t_s[i] - m.t_s.front() <= window_s; ++i) {
    const double dt = 0.5 * (m.t_s[i] - m.t_s[i - 2]);
    const double a =
        (m.position_mm[i] - 2.0 * m.position_mm[i - 1] + m.position_mm[i - 2]) / (dt * dt);
    ss += a * a * dt;
    ++n;
  }
  return n > 0 ? std::max(ss / static_cast<double>(n), 1.0) : 1e4;
}

// The measurement noise the EKF will estimate, for the constant-velocity KF (the same
// batch fit on the same window).
double InitialNoise(const MotionTrace& m, const HeartbeatEkfOptions& e) {
  std::size_t n = 0;
  while (n < m.size() && m.t_s[n] - m.t_s.front() < e.init_window_s) ++n;
  n = std::min(n + 1, m.size());
  HarmonicFitOptions fo;
  fo.min_rate_hz = e.min_rate_hz;
  fo.max_rate_hz = e.max_rate_hz;
  fo.harmonics = e.harmonics;
  fo.max_harmonics = e.max_harmonics;
  fo.trend_order = 3;
  const HarmonicFit fit = FitHarmonics(m.t_s.data(), m.position_mm.data(), n, m.t_s[n - 1], fo);
  return std::max(fit.noise_mm, 0.02);
}

}  // namespace

PredictionRun RunPrediction(const MotionTrace& trace, const PredictionRunOptions& o) {
  ValidateMotionTrace(trace);
  if (o.truth != nullptr) ValidateMotionTrace(*o.truth);
  if (!(std::isfinite(o.latency_s) && o.latency_s >= 0.0 && o.latency_s <= 2.0)) {
    throw std::invalid_argument("--latency must be in [0, 2] s");
  }
  const MotionTrace measured =
      o.measurement_rate_hz > 0.0 ? ResampleTrace(trace, o.measurement_rate_hz) : trace;
  const MotionTrace& reference = o.truth != nullptr ? *o.truth : trace;
  const double needed = o.ekf.init_window_s + o.latency_s;
  if (measured.size() < 2 || measured.duration_s() <= needed) {
    throw std::invalid_argument(
        trace.source + ": the trace spans " + std::to_string(trace.duration_s()) +
        " s; the predictor needs more than " + std::to_string(needed) +
        " s (its initialisation window, at least one beat at the lowest rate, plus the latency)");
  }

  PredictionRun run;
  run.measurements = measured.size();
  run.gaps = FindGaps(measured).size();
  run.measurement_rate_hz = 1.0 / MedianInterval(measured);
  PredictorCompetitionOptions co;
  co.latency_s = o.latency_s;
  co.window_s = o.competition_window_s;
  co.combination = o.combination;
  co.ekf = o.ekf;
  co.ar = o.ar;
  co.cv.accel_psd_mm2_s3 = CvAccelPsd(measured, o.ekf.init_window_s);
  co.cv.noise_mm = o.ekf.noise_mm > 0.0 ? o.ekf.noise_mm : InitialNoise(measured, o.ekf);
  run.cv_accel_psd_mm2_s3 = co.cv.accel_psd_mm2_s3;
  PredictorCompetition competition(co);
  const HeartbeatEkf& ekf = competition.ekf();
  constexpr int kCount = PredictorCompetition::kCount;
  Accumulator shipped_acc;
  std::vector<Accumulator> acc(kCount);
  std::vector<std::size_t> chosen(kCount, 0);
  const TraceInterpolator truth_at(reference);
  // The reference, fitted on the first half; its predictions at the second half's
  // measurements, in order.
  if (o.reference) {
    ArReferenceOptions ro = o.reference_options;
    ro.latency_s = o.latency_s;
    try {
      run.reference = FitArReference(measured, ro);
      run.has_reference = true;
    } catch (const std::invalid_argument& e) {
      run.reference_note = e.what();
    }
  }
  const double split_s =
      run.has_reference ? run.reference.split_s : std::numeric_limits<double>::infinity();
  std::size_t ref_cursor = 0;
  Accumulator half_shipped;
  Accumulator half_reference;
  std::vector<Accumulator> half(kCount);
  bool scoring = false;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    const double t = measured.t_s[i];
    const double z = measured.position_mm[i];
    competition.Update(t, z);
    if (!scoring && ekf.initialised()) {
      scoring = true;
      run.scored_from_s = t;
    }
    if (!scoring) continue;
    const double target_t = t + o.latency_s;
    if (target_t > reference.t_s.back()) break;
    double truth = 0.0;
    if (!truth_at.At(target_t, truth)) {
      ++run.unscored_in_gaps;
      continue;
    }
    const double shipped = competition.Predict(target_t);
    const double e = shipped - truth;
    if (o.keep_series) {
      run.series.t_s.push_back(target_t);
      run.series.truth_mm.push_back(truth);
      run.series.shipped_mm.push_back(shipped);
      run.series.chosen.push_back(static_cast<int>(competition.chosen()));
    }
    shipped_acc.Add(e);
    const bool second_half = t >= split_s;
    if (second_half) {
      const auto& rt = run.reference.t_s;
      while (ref_cursor < rt.size() && rt[ref_cursor] < t) ++ref_cursor;
      assert(ref_cursor < rt.size() && rt[ref_cursor] == t);
      half_reference.Add(run.reference.predicted_mm[ref_cursor] - truth);
      half_shipped.Add(e);
    }
    ++chosen[static_cast<std::size_t>(competition.chosen())];
    if (o.keep_errors) run.shipped_errors_mm.push_back(e);
    for (int c = 0; c < kCount; ++c) {
      const double ec = competition.competitor(c).Predict(target_t) - truth;
      acc[static_cast<std::size_t>(c)].Add(ec);
      if (second_half) half[static_cast<std::size_t>(c)].Add(ec);
      if (o.keep_errors && c == PredictorCompetition::kEkf) run.ekf_errors_mm.push_back(ec);
    }
  }
  if (shipped_acc.n == 0) {
    throw std::invalid_argument(trace.source +
                                ": nothing to score: no measurement after the predictor's "
                                "initialisation has a reference `latency` later");
  }
  run.scored = shipped_acc.n;
  run.shipped = shipped_acc.Score(competition.name());
  for (int c = 0; c < kCount; ++c) {
    const auto u = static_cast<std::size_t>(c);
    const std::string& name = competition.competitor(c).name();
    run.competitors.push_back(acc[u].Score(name));
    run.chosen_fraction.emplace_back(
        name, static_cast<double>(chosen[u]) / static_cast<double>(shipped_acc.n));
    if (c >= PredictorCompetition::kZoh) run.baselines.push_back(run.competitors.back());
  }
  run.ekf = run.competitors[PredictorCompetition::kEkf];
  if (run.has_reference && half_shipped.n == 0) {
    run.has_reference = false;
    run.reference_note =
        trace.source + ": no second-half measurement has a reference `latency` later";
  }
  if (run.has_reference) {
    SecondHalfScores& h = run.second_half;
    h.split_s = split_s;
    h.scored = half_shipped.n;
    h.shipped = half_shipped.Score(competition.name());
    h.reference = half_reference.Score("autoregressive_reference");
    for (int c = 0; c < kCount; ++c)
      h.competitors.push_back(half[static_cast<std::size_t>(c)].Score(
          run.competitors[static_cast<std::size_t>(c)].name));
  }
  run.switches = competition.switches();
  run.reacquisitions = ekf.reacquisitions();
  run.ar_order = competition.ar().order();
  run.ar_horizon_steps = competition.ar().horizon_steps();
  run.ls_ar_order = competition.ls_ar().order();
  run.ls_ar_stride = competition.ls_ar().stride();
  run.blend_ekf_weight = competition.blend_ekf_weight();
  run.harmonics = ekf.harmonics();
  run.respiration = ekf.respiration();
  run.offset_rate_q_mm_s = ekf.offset_rate_q_mm_s();
  run.rate_hz = ekf.rate_hz();
  {
    // The newest heart_rate_window_s of measurements, within the EKF's search range.
    std::size_t first = 0;
    while (first + 16 < measured.size() &&
           measured.t_s.back() - measured.t_s[first] > o.heart_rate_window_s)
      ++first;
    HeartRateOptions ho;
    ho.min_hz = o.ekf.min_rate_hz;
    ho.max_hz = o.ekf.max_rate_hz;
    ho.max_analysis_hz = std::max(ho.max_analysis_hz, 2.5 * ho.max_hz);
    run.heart_rate =
        EstimateHeartRate(measured.t_s.data() + first, measured.position_mm.data() + first,
                          measured.size() - first, ho);
    run.heart_rate_window_s = measured.t_s.back() - measured.t_s[first];
  }
  run.noise_mm = ekf.noise_mm();
  run.accepted = ekf.accepted();
  run.rejected = ekf.rejected();
  run.initialisations = ekf.initialisations();
  return run;
}

}  // namespace echoservo::estimation
