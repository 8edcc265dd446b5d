#include "lab/motion_noise.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "estimation/harmonic_fit.h"

namespace echoservo::lab {
namespace {

constexpr int kNoiseMinOrder = 2;
constexpr int kNoiseMaxOrder = 6;
constexpr double kNoiseMinRateHz = 0.6;
constexpr double kNoiseMaxRateHz = 4.0;
constexpr int kNoiseMaxHarmonics = 8;

double NoiseMedian(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

// 1.4826·MAD: σ of a Gaussian sample, robust to a minority of outliers.
double NoiseRobustScale(const std::vector<double>& v) {
  const double m = NoiseMedian(v);
  std::vector<double> dev(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) dev[i] = std::abs(v[i] - m);
  return 1.4826 * NoiseMedian(dev);
}

// Smallest non-zero step of the signal (its quantisation), or 0.
double NoiseQuantum(const std::vector<double>& x) {
  double q = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < x.size(); ++i) {
    const double d = std::abs(x[i] - x[i - 1]);
    if (d > 0.0) q = std::min(q, d);
  }
  return std::isfinite(q) ? q : 0.0;
}

double MedianStep(const std::vector<double>& t) {
  std::vector<double> dt(t.size() - 1);
  for (std::size_t i = 1; i < t.size(); ++i) dt[i - 1] = t[i] - t[i - 1];
  return NoiseMedian(dt);
}

// The most harmonics (≤ 8) of `rate_hz` whose frequencies, folded into [0, fs/2], stay
// apart from each other, from 0 (the trend) and from fs/2 by a resolution of the window,
// leaving at least twice as many samples as parameters.
int SeparableHarmonics(double rate_hz, double fs, double span_s, std::size_t n, int trend) {
  const double resolution = 1.0 / span_s;
  std::vector<double> folded;
  for (int k = 1; k <= kNoiseMaxHarmonics; ++k) {
    const double a = std::abs(std::remainder(k * rate_hz, fs));
    bool apart = a >= resolution && 0.5 * fs - a >= 0.5 * resolution;
    for (double b : folded) apart = apart && std::abs(a - b) >= resolution;
    if (!apart || 2 * (trend + 1 + 2 * k) > static_cast<int>(n)) break;
    folded.push_back(a);
  }
  return std::max<int>(1, static_cast<int>(folded.size()));
}

// The trace's heart rate from the middle (at least 5 s, at most the whole trace); 0 when
// no heartbeat fits.
double TraceRate(const estimation::MotionTrace& trace) {
  const double mid = 0.5 * (trace.t_s.front() + trace.t_s.back());
  const double half = 0.5 * std::min(trace.duration_s(), std::max(trace.duration_s() / 3.0, 5.0));
  std::vector<double> t;
  std::vector<double> x;
  for (std::size_t i = 0; i < trace.size(); ++i) {
    if (std::abs(trace.t_s[i] - mid) <= half) {
      t.push_back(trace.t_s[i]);
      x.push_back(trace.position_mm[i]);
    }
  }
  estimation::HarmonicFitOptions o;
  o.min_rate_hz = kNoiseMinRateHz;
  o.max_rate_hz = kNoiseMaxRateHz;
  o.trend_order = 1;
  try {
    return estimation::FitHarmonics(t.data(), x.data(), t.size(), mid, o).motion.frequency_hz;
  } catch (const std::invalid_argument&) {
    return 0.0;
  }
}

}  // namespace

MotionNoise EstimateMotionNoise(const estimation::MotionTrace& trace) {
  estimation::ValidateMotionTrace(trace);
  if (trace.size() < 16 || trace.duration_s() < 2.0 / kNoiseMinRateHz) {
    throw std::invalid_argument(trace.source + ": " + std::to_string(trace.size()) +
                                " samples over " + std::to_string(trace.duration_s()) +
                                " s are too few to estimate the noise (at least 16 samples "
                                "and two beats at 36 bpm: 3.3 s)");
  }
  MotionNoise out;
  // Differences of order k: Var(Δᵏe) = C(2k, k)·σ² for white noise e.
  out.difference_mm = std::numeric_limits<double>::infinity();
  std::vector<double> d = trace.position_mm;
  double binom = 2.0;  // C(2k, k) for k = 1
  for (int k = 1; k <= kNoiseMaxOrder && d.size() > 8; ++k) {
    for (std::size_t i = 0; i + 1 < d.size(); ++i) d[i] = d[i + 1] - d[i];
    d.pop_back();
    if (k > 1) binom *= 2.0 * (2.0 * k - 1.0) / k;  // C(2k,k) = C(2k−2,k−1)·2(2k−1)/k
    if (k < kNoiseMinOrder) continue;
    const double s = NoiseRobustScale(d) / std::sqrt(binom);
    if (s < out.difference_mm) {
      out.difference_mm = s;
      out.difference_order = k;
    }
  }
  // Windowed heartbeat fits.
  out.rate_hz = TraceRate(trace);
  out.local_fit_mm = std::numeric_limits<double>::infinity();
  std::vector<double> centres;
  std::vector<double> rates;
  if (out.rate_hz > 0.0) {
    const double window = std::max(3.0, 3.0 / out.rate_hz);
    const auto count = static_cast<std::size_t>(std::floor(trace.duration_s() / window));
    std::vector<double> sigmas;
    std::size_t i = 0;
    for (std::size_t w = 0; w < count; ++w) {
      const double end = trace.t_s.front() + static_cast<double>(w + 1) * window;
      std::vector<double> t;
      std::vector<double> x;
      for (; i < trace.size() && trace.t_s[i] < end; ++i) {
        t.push_back(trace.t_s[i]);
        x.push_back(trace.position_mm[i]);
      }
      if (t.size() < 16 || t.back() - t.front() < 0.8 * window) continue;
      estimation::HarmonicFitOptions o;
      o.min_rate_hz = 0.8 * out.rate_hz;
      o.max_rate_hz = 1.25 * out.rate_hz;
      o.trend_order = 3;
      try {
        const double centre = 0.5 * (t.front() + t.back());
        const double rate =
            estimation::FitHarmonics(t.data(), x.data(), t.size(), centre, o).motion.frequency_hz;
        // Refit at that rate with every harmonic the sampling can tell apart, aliased ones
        // included (a harmonic above the Nyquist rate is still a sinusoid in the samples).
        const int harmonics = SeparableHarmonics(rate, 1.0 / MedianStep(t), t.back() - t.front(),
                                                 t.size(), o.trend_order);
        const estimation::HarmonicFit fit = estimation::FitHarmonicsAtRate(
            t.data(), x.data(), t.size(), centre, rate, harmonics, o.trend_order);
        sigmas.push_back(fit.noise_mm);
        centres.push_back(centre);
        rates.push_back(60.0 * rate);
      } catch (const std::invalid_argument&) {
        // Too few samples for any harmonic at this rate: this window has no estimate.
      }
    }
    if (!sigmas.empty()) out.local_fit_mm = NoiseMedian(sigmas);
  }
  const double floor = std::max(NoiseQuantum(trace.position_mm) / std::sqrt(12.0), 1e-3);
  out.position_mm = std::max(std::min(out.difference_mm, out.local_fit_mm), floor);
  // Local rate at every sample.
  out.local_rate_bpm.assign(trace.size(), 60.0 * out.rate_hz);
  if (!centres.empty()) {
    std::size_t w = 0;
    for (std::size_t s = 0; s < trace.size(); ++s) {
      const double t = trace.t_s[s];
      while (w + 1 < centres.size() && centres[w + 1] <= t) ++w;
      if (t <= centres.front()) {
        out.local_rate_bpm[s] = rates.front();
      } else if (w + 1 >= centres.size()) {
        out.local_rate_bpm[s] = rates.back();
      } else {
        const double u = (t - centres[w]) / (centres[w + 1] - centres[w]);
        out.local_rate_bpm[s] = rates[w] + u * (rates[w + 1] - rates[w]);
      }
    }
  }
  return out;
}

}  // namespace echoservo::lab
