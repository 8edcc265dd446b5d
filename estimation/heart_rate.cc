#include "estimation/heart_rate.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "estimation/fourier_motion.h"
#include "estimation/heartbeat_significance.h"

namespace echoservo::estimation {
namespace {

constexpr double kAcfTolerance = 0.15;    // |lag·f₀ − 1| for agreement
constexpr double kHalfPeriodShare = 0.8;  // half-period repetition this close: a sub-harmonic
constexpr int kTrendOrder = 2;            // quadratic detrend
constexpr int kGoldenIterations = 30;

std::string RateFormat(const char* f, auto... args) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

// The trace on a uniform grid at rate fs (block means when the trace is denser than 1.5 fs,
// linear interpolation otherwise), quadratic trend removed.
std::vector<double> UniformDetrended(const double* t, const double* x, std::size_t n, double fs) {
  const double span = t[n - 1] - t[0];
  const auto m = static_cast<std::size_t>(std::floor(span * fs)) + 1;
  std::vector<double> y(m);
  const double native = static_cast<double>(n - 1) / span;
  if (native > 1.5 * fs) {
    std::size_t j = 0;
    for (std::size_t g = 0; g < m; ++g) {
      const double lo = t[0] + (static_cast<double>(g) - 0.5) / fs;
      const double hi = lo + 1.0 / fs;
      while (j < n && t[j] < lo) ++j;
      double sum = 0.0;
      std::size_t count = 0;
      for (std::size_t k = j; k < n && t[k] < hi; ++k, ++count) sum += x[k];
      y[g] = count > 0 ? sum / static_cast<double>(count) : (g > 0 ? y[g - 1] : x[0]);
    }
  } else {
    std::size_t j = 0;
    for (std::size_t g = 0; g < m; ++g) {
      const double tg = t[0] + static_cast<double>(g) / fs;
      while (j + 2 < n && t[j + 1] < tg) ++j;
      const double u = std::clamp((tg - t[j]) / (t[j + 1] - t[j]), 0.0, 1.0);
      y[g] = x[j] + u * (x[j + 1] - x[j]);
    }
  }
  // Least-squares quadratic in a centred, scaled time.
  Eigen::MatrixXd a(static_cast<Eigen::Index>(m), kTrendOrder + 1);
  const double mid = 0.5 * static_cast<double>(m - 1);
  for (std::size_t g = 0; g < m; ++g) {
    const double s = (static_cast<double>(g) - mid) / std::max(mid, 1.0);
    for (int p = 0; p <= kTrendOrder; ++p) a(static_cast<Eigen::Index>(g), p) = std::pow(s, p);
  }
  const Eigen::Map<Eigen::VectorXd> yv(y.data(), static_cast<Eigen::Index>(m));
  const Eigen::VectorXd c = a.colPivHouseholderQr().solve(yv);
  const Eigen::VectorXd r = yv - a * c;
  return {r.data(), r.data() + r.size()};
}

class Spectrum {
 public:
  Spectrum(const std::vector<double>& y, double fs) : y_(y), fs_(fs) {}
  // A²(f): the squared amplitude of the sinusoid at f (Goertzel-free complex recurrence).
  double Power(double f) const {
    const std::complex<double> step = std::polar(1.0, -kTwoPi * f / fs_);
    std::complex<double> z = 1.0;
    std::complex<double> sum = 0.0;
    for (std::size_t j = 0; j < y_.size(); ++j) {
      sum += y_[j] * z;
      z *= step;
      if ((j & 63) == 63) z /= std::abs(z);  // keep the rotation on the unit circle
    }
    const double scale = 2.0 / static_cast<double>(y_.size());
    return std::norm(sum) * scale * scale;
  }
  double nyquist() const { return 0.5 * fs_; }

 private:
  const std::vector<double>& y_;
  double fs_;
};

// Harmonics of f₀ below 0.9 Nyquist, at most k_max.
int UsableHarmonics(double f0, int k_max, double nyquist) {
  return std::clamp(static_cast<int>(std::floor(0.9 * nyquist / f0)), 1, k_max);
}

// The residual sum of squares of a least-squares fit of y on [trend; harmonics of f₀].
double HarmonicRss(const std::vector<double>& y, double fs, double f0, int harmonics) {
  const auto m = static_cast<Eigen::Index>(y.size());
  Eigen::MatrixXd a(m, 1 + 2 * harmonics);
  for (Eigen::Index g = 0; g < m; ++g) {
    a(g, 0) = 1.0;
    const double w = kTwoPi * f0 * static_cast<double>(g) / fs;
    for (int k = 1; k <= harmonics; ++k) {
      a(g, 2 * k - 1) = std::cos(k * w);
      a(g, 2 * k) = std::sin(k * w);
    }
  }
  const Eigen::Map<const Eigen::VectorXd> yv(y.data(), m);
  const Eigen::VectorXd c = a.colPivHouseholderQr().solve(yv);
  return (yv - a * c).squaredNorm();
}

// The normalised autocorrelation of y at lag (samples).
double Acf(const std::vector<double>& y, std::size_t lag, double variance) {
  if (lag >= y.size()) return 0.0;
  double s = 0.0;
  for (std::size_t j = lag; j < y.size(); ++j) s += y[j] * y[j - lag];
  return s / static_cast<double>(y.size() - lag) / variance;
}

}  // namespace

HeartRateEstimate EstimateHeartRate(const double* t, const double* x, std::size_t n,
                                    const HeartRateOptions& o) {
  if (!(std::isfinite(o.min_hz) && o.min_hz > 0.0 && o.max_hz > o.min_hz && o.harmonics >= 1 &&
        o.harmonics <= 12 && o.false_alarm > 0.0 && o.false_alarm < 1.0 &&
        o.max_analysis_hz > 2.0 * o.max_hz && o.min_repeat_correlation > -1.0 &&
        o.min_repeat_correlation < 1.0)) {
    throw std::invalid_argument(
        "heart rate: 0 < min_hz < max_hz, 1 <= harmonics <= 12, false_alarm in (0, 1), "
        "max_analysis_hz > 2 max_hz, min_repeat_correlation in (-1, 1)");
  }
  if (n < 16) throw std::invalid_argument("heart rate: at least 16 samples are needed");
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(t[i]) || !std::isfinite(x[i]))
      throw std::invalid_argument("heart rate: sample " + std::to_string(i) + " is not finite");
    if (i > 0 && !(t[i] > t[i - 1]))
      throw std::invalid_argument("heart rate: times must be strictly increasing (sample " +
                                  std::to_string(i) + ")");
  }
  HeartRateEstimate r;
  const double span = t[n - 1] - t[0];
  const double native = static_cast<double>(n - 1) / span;
  const double fs = std::min(native, o.max_analysis_hz);
  // At least two beats in the trace, and the fundamental below Nyquist.
  const double lo = std::max(o.min_hz, 2.0 / span);
  const double hi = std::min(o.max_hz, 0.45 * fs);
  r.rate_hz = std::clamp(o.min_hz, o.min_hz, o.max_hz);
  if (!(hi > lo)) {
    r.reason =
        RateFormat("too short or too sparse: %.1f s at %.1f Hz holds no two beats in %.0f-%.0f bpm",
                   span, native, 60.0 * o.min_hz, 60.0 * o.max_hz);
    return r;
  }
  const std::vector<double> y = UniformDetrended(t, x, n, fs);
  double variance = 0.0;
  for (double v : y) variance += v * v;
  variance /= static_cast<double>(y.size());
  if (!(variance > 0.0)) {
    r.reason = "no motion: the detrended trace is constant";
    return r;
  }
  const Spectrum spectrum(y, fs);
  const double t_span = static_cast<double>(y.size()) / fs;
  // The spectrum on a grid 4× finer than 1/span up to the K-th harmonic of the band's top.
  const double df = 0.25 / t_span;
  const double f_top = std::min(spectrum.nyquist(), o.harmonics * hi + df);
  std::vector<double> grid;
  for (double f = df; f <= f_top; f += df) grid.push_back(spectrum.Power(f));
  auto grid_power = [&](double f) {  // the grid's max within ±1 bin of f
    const long c = std::lround(f / df) - 1;
    double best = 0.0;
    for (long i = c - 1; i <= c + 1; ++i)
      if (i >= 0 && i < static_cast<long>(grid.size()))
        best = std::max(best, grid[static_cast<std::size_t>(i)]);
    return best;
  };
  auto harmonic_sum = [&](double f0, auto&& power) {
    double s = 0.0;
    const int k_max = UsableHarmonics(f0, o.harmonics, spectrum.nyquist());
    for (int k = 1; k <= k_max; ++k) s += power(k * f0);
    return s;
  };
  auto exact = [&](double f) { return spectrum.Power(f); };
  // The band's best harmonic sum on the grid (candidate step df / K), then golden section.
  const double step = df / o.harmonics;
  double best_f = lo;
  double best_hs = -1.0;
  for (double f0 = lo; f0 <= hi; f0 += step) {
    const double hs = harmonic_sum(f0, grid_power);
    if (hs > best_hs) {
      best_hs = hs;
      best_f = f0;
    }
  }
  auto refine = [&](double f0) {
    double a = std::max(lo, f0 - df), b = std::min(hi, f0 + df);
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    for (int i = 0; i < kGoldenIterations; ++i) {
      const double c = b - g * (b - a), d = a + g * (b - a);
      if (harmonic_sum(c, exact) > harmonic_sum(d, exact))
        b = d;
      else
        a = c;
    }
    return 0.5 * (a + b);
  };
  double f0 = refine(best_f);
  // Sub-harmonic and harmonic checks by nested regressions (leakage cannot fool them): f₀
  // is a sub-harmonic when its odd harmonics add nothing significant to the model of 2f₀;
  // f₀/m is the fundamental when its harmonics between f₀'s add something significant.
  const double f_model_top = 0.9 * spectrum.nyquist();
  auto adds = [&](double f_coarse, double f_fine) {  // does f_fine's model beat f_coarse's?
    const int kc = UsableHarmonics(f_coarse, o.harmonics, spectrum.nyquist());
    const int kf = std::clamp(static_cast<int>(std::floor(kc * f_coarse / f_fine + 1e-9)), 1,
                              static_cast<int>(std::floor(f_model_top / f_fine)));
    const double rss_c = HarmonicRss(y, fs, f_coarse, kc);
    const double rss_f = HarmonicRss(y, fs, f_fine, kf);
    const double d = 2.0 * (kf - kc);
    const double d2 = static_cast<double>(y.size()) - 2.0 * kf - 1.0;
    if (d <= 0.0 || d2 <= 0.0 || !(rss_f > 0.0)) return rss_f < rss_c;
    const double f = ((rss_c - rss_f) / d) / (rss_f / d2);
    return FisherFSurvival(f, d, d2) < o.false_alarm;
  };
  for (int round = 0; round < 3; ++round) {
    if (2.0 * f0 <= hi && !adds(2.0 * f0, f0)) {
      f0 = refine(2.0 * f0);
      ++r.corrections;
      continue;
    }
    double divided = 0.0;
    for (int m : {3, 2}) {
      const double f = f0 / m;
      if (f >= lo && adds(f0, f)) {
        divided = f;
        break;
      }
    }
    if (divided > 0.0) {
      f0 = refine(divided);
      ++r.corrections;
      continue;
    }
    break;
  }
  r.rate_hz = std::clamp(f0, o.min_hz, o.max_hz);
  r.fundamental_share = exact(f0) / std::max(harmonic_sum(f0, exact), 1e-300);
  // A harmonic of a stronger, slower motion below the band (respiration)? Its line: the
  // strongest below the band; f₀ is its harmonic when within half a resolution bin of a
  // multiple of it.
  if (lo > 2.0 / t_span) {
    double f_slow = 0.0, p_slow = 0.0;
    for (double f = 2.0 / t_span; f < lo; f += df) {
      const double p = exact(f);
      if (p > p_slow) {
        p_slow = p;
        f_slow = f;
      }
    }
    const double p_f0 = exact(f0);
    if (f_slow > 0.0 && p_slow > p_f0) {
      const double m = std::round(f0 / f_slow);
      if (m >= 2.0 && std::abs(f0 - m * f_slow) <= m * 0.5 / t_span && adds(f0, f0 / m)) {
        r.reason = RateFormat(
            "no heartbeat: the periodicity at %.1f bpm is harmonic %.0f of a stronger one at "
            "%.1f per minute, below the %.0f bpm band (respiration?)",
            60.0 * f0, m, 60.0 * f_slow, 60.0 * o.min_hz);
        return r;
      }
    }
  }
  // The autocorrelation's peak near one period; when the motion repeats as well at half
  // that period, the candidate is a sub-harmonic the regressions let through (beat-to-beat
  // variation that a two-beat model fits): double it.
  // On the trace less its moving average over one candidate period, which removes what is
  // slower than the beat (breathing) and keeps the beat whole.
  std::vector<double> fast;
  double fast_variance = 0.0;
  auto high_pass = [&](double period_s) {
    const auto half = static_cast<std::size_t>(std::lround(0.5 * period_s * fs));
    fast.clear();
    fast_variance = 0.0;
    double sum = 0.0;
    for (std::size_t j = 0; j < std::min(y.size(), 2 * half + 1); ++j) sum += y[j];
    for (std::size_t j = half; j + half + 1 < y.size(); ++j) {
      const double v = y[j] - sum / static_cast<double>(2 * half + 1);
      fast.push_back(v);
      fast_variance += v * v;
      sum += y[j + half + 1] - y[j - half];
    }
    fast_variance /= static_cast<double>(std::max<std::size_t>(fast.size(), 1));
  };
  auto acf_peak = [&](double period_s, std::size_t& lag_out) {
    double best = -2.0;
    const auto a = static_cast<std::size_t>(std::max(1.0, std::floor(0.6 * period_s * fs)));
    const auto b = static_cast<std::size_t>(std::ceil(1.4 * period_s * fs));
    for (std::size_t lag = a; lag <= b && lag < fast.size(); ++lag) {
      const double c = fast_variance > 0.0 ? Acf(fast, lag, fast_variance) : 0.0;
      if (c > best) {
        best = c;
        lag_out = lag;
      }
    }
    return best;
  };
  high_pass(1.0 / f0);
  std::size_t best_lag = 0;
  double best_acf = acf_peak(1.0 / f0, best_lag);
  std::size_t half_lag = 0;
  const double half_acf = 2.0 * f0 <= hi ? acf_peak(0.5 / f0, half_lag) : -2.0;
  if (half_acf >= o.min_repeat_correlation && half_acf >= kHalfPeriodShare * best_acf &&
      std::abs(static_cast<double>(half_lag) / fs * 2.0 * f0 - 1.0) <= kAcfTolerance) {
    f0 = refine(2.0 * f0);
    ++r.corrections;
    r.rate_hz = std::clamp(f0, o.min_hz, o.max_hz);
    r.fundamental_share = exact(f0) / std::max(harmonic_sum(f0, exact), 1e-300);
    high_pass(1.0 / f0);
    best_acf = acf_peak(1.0 / f0, best_lag);
  }
  const double period = 1.0 / f0;
  // The F-test of the harmonic regression against the trend alone (already removed).
  const int k = UsableHarmonics(f0, o.harmonics, spectrum.nyquist());
  const double m = static_cast<double>(y.size());
  const double rss0 = variance * m;
  const double rss1 = HarmonicRss(y, fs, f0, k);
  const double d1 = 2.0 * k;
  const double d2 = m - d1 - 1.0 - kTrendOrder - 1.0;
  r.f_statistic = d2 > 0.0 && rss1 > 0.0 ? ((rss0 - rss1) / d1) / (rss1 / d2) : 1e300;
  const double independent = std::max(1.0, t_span * (hi - lo));
  r.p_value = d2 > 0.0 ? std::min(1.0, independent * FisherFSurvival(r.f_statistic, d1, d2)) : 1.0;
  r.acf_period_s = static_cast<double>(best_lag) / fs;
  r.acf_at_period = best_acf;
  r.acf_agrees =
      std::abs(r.acf_period_s * f0 - 1.0) <= kAcfTolerance && best_acf >= o.min_repeat_correlation;
  r.significant = r.p_value < o.false_alarm && r.acf_agrees;
  r.reason = RateFormat(
      "%s: %.1f bpm, F %.3g (family-wise p %.2g, threshold %.2g), autocorrelation %.2f at "
      "%.3f s (period %.3f s)%s",
      r.significant ? "heartbeat" : "no significant heartbeat", 60.0 * f0, r.f_statistic, r.p_value,
      o.false_alarm, best_acf, r.acf_period_s, period,
      r.acf_agrees ? "" : " - the motion does not repeat at this period");
  return r;
}

}  // namespace echoservo::estimation
