#include "estimation/heartbeat_significance.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <vector>

#include "estimation/fourier_motion.h"

namespace echoservo::estimation {
namespace {

constexpr int kSigTrendColumns = 3;           // 1, u, u²: a slow drift is no heartbeat
constexpr double kSigMaxHarmonicOfFs = 0.45;  // harmonics kept below 0.45 × the sampling rate
constexpr double kSigGridPerRayleigh = 4.0;   // rate grid step 1/(4T)
constexpr double kSigSearchFactor = 1.5;      // the oversampled search (Monte Carlo)
constexpr int kSigMinPairs = 6;               // lagged pairs for the repetition test
constexpr double kSigMaxGapSamples = 3.0;     // no interpolation across longer gaps
constexpr double kSigFlatVarianceMm2 = 1e-12;

// Continued fraction of the incomplete beta function (modified Lentz).
double BetaContinuedFraction(double a, double b, double x) {
  constexpr double kTiny = 1e-300;
  constexpr double kEps = 1e-15;
  const double qab = a + b;
  const double qap = a + 1.0;
  const double qam = a - 1.0;
  double c = 1.0;
  double d = 1.0 - qab * x / qap;
  if (std::abs(d) < kTiny) d = kTiny;
  d = 1.0 / d;
  double h = d;
  for (int m = 1; m <= 500; ++m) {
    const double m2 = 2.0 * m;
    double aa = m * (b - m) * x / ((qam + m2) * (a + m2));
    d = 1.0 + aa * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1.0 + aa / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    h *= d * c;
    aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
    d = 1.0 + aa * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1.0 + aa / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::abs(del - 1.0) < kEps) break;
  }
  return h;
}

// The regularised incomplete beta function I_x(a, b).
double RegularisedIncompleteBeta(double a, double b, double x) {
  if (x <= 0.0) return 0.0;
  if (x >= 1.0) return 1.0;
  const double front = std::exp(std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) +
                                a * std::log(x) + b * std::log1p(-x));
  if (x < (a + 1.0) / (a + b + 2.0)) return front * BetaContinuedFraction(a, b, x) / a;
  return 1.0 - front * BetaContinuedFraction(b, a, 1.0 - x) / b;
}

// The F value whose survival probability is p (bisection on log F).
double FisherFCritical(double p, double d1, double d2) {
  double lo = -20.0;
  double hi = 20.0;
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (FisherFSurvival(std::exp(mid), d1, d2) > p)
      lo = mid;
    else
      hi = mid;
  }
  return std::exp(0.5 * (lo + hi));
}

bool SigPositive(double v) { return std::isfinite(v) && v > 0.0; }

std::string SigFormat(const char* fmt, double a, double b, double c = 0.0) {
  char buf[200];
  std::snprintf(buf, sizeof buf, fmt, a, b, c);
  return buf;
}

}  // namespace

double FisherFSurvival(double f, double d1, double d2) {
  assert(d1 > 0.0 && d2 > 0.0);
  if (!(f > 0.0)) return 1.0;
  if (std::isinf(f)) return 0.0;
  return RegularisedIncompleteBeta(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * f));
}

HeartbeatSignificance::HeartbeatSignificance(HeartbeatSignificanceOptions options) : o_(options) {
  const bool ok = SigPositive(o_.min_rate_hz) && std::isfinite(o_.max_rate_hz) &&
                  o_.max_rate_hz > o_.min_rate_hz && SigPositive(o_.window_s) &&
                  o_.harmonics >= 1 && o_.min_beats >= 2.0 && o_.harmonics <= 12 &&
                  o_.false_alarm > 0.0 && o_.false_alarm < 1.0 &&
                  std::isfinite(o_.min_repeat_snr) && o_.min_repeat_snr >= 0.0 &&
                  std::isfinite(o_.min_p2p_sigma) && o_.min_p2p_sigma >= 0.0 &&
                  std::isfinite(o_.min_p2p_mm) && o_.min_p2p_mm >= 0.0;
  if (!ok) {
    throw std::invalid_argument(
        "heartbeat significance: rates 0 < min < max, window > 0, harmonics in [1, 12], "
        "false alarm in (0, 1) and non-negative repeat and amplitude bounds are required");
  }
  if (o_.window_s * o_.min_rate_hz < o_.min_beats) {
    throw std::invalid_argument("heartbeat significance: the window (" +
                                std::to_string(o_.window_s) +
                                " s) must hold two beats at the lowest rate");
  }
  Reset();
}

void HeartbeatSignificance::Reset() {
  window_.clear();
  evidence_ = HeartbeatEvidence{};
  evidence_.reason = "no significant heartbeat: no measurements";
}

void HeartbeatSignificance::Add(double t_s, double position_mm) {
  if (!std::isfinite(t_s) || !std::isfinite(position_mm)) {
    throw std::invalid_argument("heartbeat significance: a measurement or its time is not finite");
  }
  if (!window_.empty() && !(t_s > window_.back().first)) {
    throw std::invalid_argument(
        "heartbeat significance: measurement times must be strictly increasing");
  }
  window_.emplace_back(t_s, position_mm);
  while (t_s - window_.front().first > o_.window_s) window_.pop_front();
}

const HeartbeatEvidence& HeartbeatSignificance::Evaluate() {
  HeartbeatEvidence e;
  const std::size_t n = window_.size();
  e.samples = n;
  e.span_s = n > 0 ? window_.back().first - window_.front().first : 0.0;
  const int max_params = kSigTrendColumns + 2 * o_.harmonics;
  if (n < static_cast<std::size_t>(2 * max_params) || e.span_s <= 0.0) {
    e.reason = "no significant heartbeat: collecting (" + std::to_string(n) + " samples)";
    evidence_ = e;
    return evidence_;
  }
  std::vector<double> dts;
  dts.reserve(n - 1);
  for (std::size_t i = 1; i < n; ++i) dts.push_back(window_[i].first - window_[i - 1].first);
  std::nth_element(dts.begin(), dts.begin() + static_cast<long>(dts.size() / 2), dts.end());
  const double dt_median = dts[dts.size() / 2];
  const double fs = 1.0 / dt_median;
  const double f_lo = std::max(o_.min_rate_hz, o_.min_beats / e.span_s);  // two beats in the window
  const double f_hi = std::min(o_.max_rate_hz, kSigMaxHarmonicOfFs * fs);
  if (f_lo > f_hi) {
    e.reason = SigFormat(
        "no significant heartbeat: collecting (%.2f s holds %.3g beats only above %.2f Hz)",
        e.span_s, o_.min_beats, f_lo);
    evidence_ = e;
    return evidence_;
  }

  const double t0 = window_.front().first;
  const double t_mid = 0.5 * (t0 + window_.back().first);
  Eigen::VectorXd t(n), z(n);
  for (std::size_t i = 0; i < n; ++i) {
    t(static_cast<long>(i)) = window_[i].first - t0;
    z(static_cast<long>(i)) = window_[i].second;
  }
  const long ni = static_cast<long>(n);
  Eigen::MatrixXd x0(ni, kSigTrendColumns);
  for (long i = 0; i < ni; ++i) {
    const double u = (window_[static_cast<std::size_t>(i)].first - t_mid) / e.span_s;
    x0(i, 0) = 1.0;
    x0(i, 1) = u;
    x0(i, 2) = u * u;
  }
  const Eigen::VectorXd b0 = (x0.transpose() * x0).ldlt().solve(x0.transpose() * z);
  const Eigen::VectorXd y = z - x0 * b0;  // detrended trace
  const double rss0 = y.squaredNorm();
  if (rss0 / static_cast<double>(n) < kSigFlatVarianceMm2) {
    e.reason = "no significant heartbeat: the trace is flat";
    evidence_ = e;
    return evidence_;
  }

  // Harmonic regression over the rate grid: the smallest p of the F-test against the trend.
  struct Best {
    double p = 2.0, f = 0.0, rate = 0.0, d1 = 0.0, d2 = 0.0, rss = 0.0;
    Eigen::VectorXd coef;
    int k = 0;
  } best;
  const double step = 1.0 / (kSigGridPerRayleigh * e.span_s);
  const int steps = static_cast<int>(std::floor((f_hi - f_lo) / step)) + 1;
  for (int s = 0; s < steps; ++s) {
    const double rate = std::min(f_lo + s * step, f_hi);
    const int k = std::max(
        1, std::min(o_.harmonics, static_cast<int>(std::floor(kSigMaxHarmonicOfFs * fs / rate))));
    const int p = kSigTrendColumns + 2 * k;
    const double d1 = 2.0 * k;
    const double d2 = static_cast<double>(ni - p);
    if (d2 < 3.0) continue;
    Eigen::MatrixXd x(ni, p);
    x.leftCols(kSigTrendColumns) = x0;
    for (long i = 0; i < ni; ++i) {
      const double w = kTwoPi * rate * t(i);
      const double c1 = std::cos(w);
      const double s1 = std::sin(w);
      double ch = c1;
      double sh = s1;
      for (int h = 1; h <= k; ++h) {  // cos hw, sin hw by the angle-addition recurrence
        x(i, kSigTrendColumns + 2 * h - 2) = ch;
        x(i, kSigTrendColumns + 2 * h - 1) = sh;
        const double next = ch * c1 - sh * s1;
        sh = sh * c1 + ch * s1;
        ch = next;
      }
    }
    const Eigen::VectorXd b = (x.transpose() * x).ldlt().solve(x.transpose() * z);
    const double rss1 = (z - x * b).squaredNorm();
    const double f =
        rss1 > 0.0 ? ((rss0 - rss1) / d1) / (rss1 / d2) : std::numeric_limits<double>::infinity();
    const double pv = FisherFSurvival(f, d1, d2);
    if (pv < best.p || (pv == best.p && f > best.f)) {
      best.p = pv;
      best.f = f;
      best.rate = rate;
      best.d1 = d1;
      best.d2 = d2;
      best.rss = rss1;
      best.coef = b.tail(2 * k);
      best.k = k;
    }
  }
  if (best.k == 0) {
    e.reason = "no significant heartbeat: collecting (too few samples for the harmonic fit)";
    evidence_ = e;
    return evidence_;
  }
  // Bonferroni over the band's independent rates: the K-th harmonic resolves the
  // fundamental to 1/(K·T) (Rayleigh resolution 1/T at K·f), so ≈ K·T·band tests.
  const double tests = kSigSearchFactor * (f_hi - f_lo) * e.span_s * o_.harmonics + 1.0;
  e.rate_hz = best.rate;
  e.peak_snr = best.f;
  e.p_value = std::min(1.0, tests * best.p);
  e.snr_threshold = FisherFCritical(o_.false_alarm / tests, best.d1, best.d2);
  e.noise_mm = std::sqrt(best.rss / best.d2);
  double lo = std::numeric_limits<double>::infinity();
  double hi = -lo;
  for (int i = 0; i < 128; ++i) {
    const double w = kTwoPi * i / 128.0;
    double v = 0.0;
    for (int h = 1; h <= best.k; ++h)
      v += best.coef(2 * h - 2) * std::cos(h * w) + best.coef(2 * h - 1) * std::sin(h * w);
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  e.p2p_mm = hi - lo;

  // Repetition at the period: y(t + P) (linear interpolation) against y(t).
  const double period = 1.0 / best.rate;
  double diff2 = 0.0;
  int pairs = 0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double target = window_[i].first + period;
    if (target > window_.back().first) break;
    while (j + 1 < n && window_[j + 1].first < target) ++j;
    if (j + 1 >= n) break;
    const double ta = window_[j].first;
    const double tb = window_[j + 1].first;
    if (tb - ta > kSigMaxGapSamples * dt_median) continue;
    const double w = (target - ta) / (tb - ta);
    const double yi = (1.0 - w) * y(static_cast<long>(j)) + w * y(static_cast<long>(j + 1));
    diff2 += std::pow(yi - y(static_cast<long>(i)), 2);
    ++pairs;
  }
  const double var_total = rss0 / static_cast<double>(n);
  const double var_unrepeated = pairs > 0 ? diff2 / (2.0 * pairs) : 0.0;
  e.repeat_snr = pairs >= kSigMinPairs && var_unrepeated > 0.0
                     ? var_total / var_unrepeated - 1.0
                     : (pairs >= kSigMinPairs ? std::numeric_limits<double>::infinity() : 0.0);

  const double p2p_min = std::max(o_.min_p2p_sigma * e.noise_mm, o_.min_p2p_mm);
  if (!(e.p_value < o_.false_alarm)) {
    e.reason = SigFormat("no significant heartbeat: peak SNR %.3g < %.3g (F-test, false alarm %g)",
                         e.peak_snr, e.snr_threshold, o_.false_alarm);
  } else if (!(e.repeat_snr >= o_.min_repeat_snr)) {
    e.reason = SigFormat(
        "no significant heartbeat: the %.2f Hz fit does not repeat (repeat SNR %.3g < %.3g)",
        e.rate_hz, e.repeat_snr, o_.min_repeat_snr);
  } else if (!(e.p2p_mm >= p2p_min)) {
    e.reason =
        SigFormat("no significant heartbeat: amplitude %.3g mm p2p < %.3g mm (noise %.3g mm)",
                  e.p2p_mm, p2p_min, e.noise_mm);
  } else {
    e.significant = true;
    e.reason = SigFormat("heartbeat %.2f Hz: peak SNR %.3g >= %.3g", e.rate_hz, e.peak_snr,
                         e.snr_threshold) +
               SigFormat(", repeat SNR %.3g, %.3g mm p2p", e.repeat_snr, e.p2p_mm);
  }
  evidence_ = e;
  return evidence_;
}

}  // namespace echoservo::estimation
