#include "estimation/harmonic_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

namespace echoservo::estimation {
namespace {

struct Window {
  const double* t;
  const double* x;
  std::size_t n;
  double t_ref;
  double Scale() const { return std::max(t[n - 1] - t[0], 1e-9); }
};

int BaseColumns(int trend_order) { return trend_order + 1; }

Eigen::MatrixXd Design(const Window& w, double rate_hz, int harmonics, int trend_order) {
  const int base = BaseColumns(trend_order);
  const double scale = w.Scale();
  Eigen::MatrixXd a(static_cast<Eigen::Index>(w.n), base + 2 * harmonics);
  for (std::size_t i = 0; i < w.n; ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    const double tau = w.t[i] - w.t_ref;
    double u = 1.0;
    for (int j = 0; j < base; ++j) {
      a(r, j) = u;
      u *= tau / scale;
    }
    const double ph = kTwoPi * rate_hz * tau;
    const double c1 = std::cos(ph);
    const double s1 = std::sin(ph);
    double c = c1;
    double s = s1;
    for (int k = 0; k < harmonics; ++k) {
      a(r, base + 2 * k) = c;
      a(r, base + 2 * k + 1) = s;
      const double next = c * c1 - s * s1;
      s = s * c1 + c * s1;
      c = next;
    }
  }
  return a;
}

// Residual sum of squares for N = 1..harmonics (index N−1) from one QR.
std::vector<double> NestedRss(const Window& w, double rate_hz, int harmonics, int trend) {
  const Eigen::MatrixXd a = Design(w, rate_hz, harmonics, trend);
  const Eigen::Map<const Eigen::VectorXd> y(w.x, static_cast<Eigen::Index>(w.n));
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(a);
  const Eigen::VectorXd qty = qr.householderQ().transpose() * y;
  const double total = y.squaredNorm();
  std::vector<double> rss(static_cast<std::size_t>(harmonics));
  double explained = 0.0;
  const int base = BaseColumns(trend);
  for (int j = 0; j < base; ++j) explained += qty(j) * qty(j);
  for (int k = 0; k < harmonics; ++k) {
    explained +=
        qty(base + 2 * k) * qty(base + 2 * k) + qty(base + 2 * k + 1) * qty(base + 2 * k + 1);
    rss[static_cast<std::size_t>(k)] = std::max(total - explained, 1e-12 * total + 1e-300);
  }
  return rss;
}

double Bic(double rss, std::size_t n, int params) {
  const auto dn = static_cast<double>(n);
  return dn * std::log(rss / dn) + params * std::log(dn);
}

double MedianStep(const Window& w) {
  std::vector<double> dt;
  for (std::size_t i = 1; i < w.n; ++i) dt.push_back(w.t[i] - w.t[i - 1]);
  std::nth_element(dt.begin(), dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2), dt.end());
  return dt[dt.size() / 2];
}

}  // namespace

HarmonicFit FitHarmonicsAtRate(const double* t_s, const double* x_mm, std::size_t n, double t_ref_s,
                               double rate_hz, int harmonics, int trend) {
  const Window w{t_s, x_mm, n, t_ref_s};
  const int p = BaseColumns(trend) + 2 * harmonics;
  if (harmonics < 1 || n < static_cast<std::size_t>(p + 1)) {
    throw std::invalid_argument("harmonic fit: " + std::to_string(n) + " samples cannot fit " +
                                std::to_string(harmonics) + " harmonic(s)");
  }
  const Eigen::MatrixXd a = Design(w, rate_hz, harmonics, trend);
  const Eigen::Map<const Eigen::VectorXd> y(x_mm, static_cast<Eigen::Index>(n));
  const Eigen::VectorXd beta = a.householderQr().solve(y);
  const double rss = (a * beta - y).squaredNorm();

  HarmonicFit fit;
  fit.harmonics = harmonics;
  fit.samples = n;
  fit.residual_rms_mm = std::sqrt(rss / static_cast<double>(n));
  fit.noise_mm = std::sqrt(rss / static_cast<double>(n - static_cast<std::size_t>(p)));
  FourierMotion& m = fit.motion;
  m.t0_s = t_ref_s;
  m.frequency_hz = rate_hz;
  m.offset_mm = beta(0);
  m.drift_mm_s = trend > 0 ? beta(1) / w.Scale() : 0.0;
  const int base = BaseColumns(trend);
  // Rotate so that the fundamental is a pure cosine of the phase θ = ωτ − ψ.
  const double psi = std::atan2(beta(base + 1), beta(base));
  m.phase0_rad = -psi;
  for (int k = 1; k <= harmonics; ++k) {
    const double ak = beta(base + 2 * (k - 1));
    const double bk = beta(base + 2 * (k - 1) + 1);
    const double c = std::cos(k * psi);
    const double s = std::sin(k * psi);
    m.cos_mm.push_back(ak * c + bk * s);
    m.sin_mm.push_back(k == 1 ? 0.0 : -ak * s + bk * c);
  }
  return fit;
}

HarmonicFit FitHarmonics(const double* t_s, const double* x_mm, std::size_t n, double t_ref_s,
                         const HarmonicFitOptions& o) {
  if (!(o.min_rate_hz > 0.0 && o.max_rate_hz > o.min_rate_hz)) {
    throw std::invalid_argument("harmonic fit: need 0 < min rate < max rate");
  }
  if (o.trend_order < 0 || o.trend_order > 3) {
    throw std::invalid_argument("harmonic fit: trend order must be in [0, 3]");
  }
  if (o.harmonics < 0 || o.max_harmonics < 1 || o.harmonics > 30 || o.max_harmonics > 30) {
    throw std::invalid_argument("harmonic fit: harmonics must be in [1, 30] (0: automatic)");
  }
  if (n < 8) {
    throw std::invalid_argument("harmonic fit: " + std::to_string(n) +
                                " samples are too few to fit a heartbeat");
  }
  const double span = t_s[n - 1] - t_s[0];
  if (span * o.min_rate_hz < 1.0) {
    throw std::invalid_argument("harmonic fit: " + std::to_string(span) +
                                " s of data hold less than one beat at the lowest rate (" +
                                std::to_string(o.min_rate_hz * 60.0) + " bpm)");
  }
  const Window w{t_s, x_mm, n, t_ref_s};
  const double fs = 1.0 / MedianStep(w);
  const int base = BaseColumns(o.trend_order);
  const int n_max = o.harmonics > 0 ? o.harmonics : o.max_harmonics;
  // Harmonics allowed at rate f: below 0.45·fs and leaving at least as many samples as
  // parameters twice over.
  auto allowed = [&](double f) {
    int k = std::min(n_max, static_cast<int>(std::floor(0.45 * fs / f)));
    while (k > 0 && static_cast<std::size_t>(2 * (base + 2 * k)) > n) --k;
    return k;
  };
  auto best_at = [&](double f, int& best_n) {
    const int k = allowed(f);
    best_n = 0;
    if (k < 1 || (o.harmonics > 0 && k < o.harmonics))
      return std::numeric_limits<double>::infinity();
    const std::vector<double> rss = NestedRss(w, f, k, o.trend_order);
    double best = std::numeric_limits<double>::infinity();
    const int first = o.harmonics > 0 ? o.harmonics : 1;
    for (int h = first; h <= k; ++h) {
      const double b = Bic(rss[static_cast<std::size_t>(h - 1)], n, base + 2 * h + 1);
      if (b < best) {
        best = b;
        best_n = h;
      }
    }
    return best;
  };
  const double step = 1.0 / (30.0 * span);
  double best_f = 0.0;
  int best_n = 0;
  double best_bic = std::numeric_limits<double>::infinity();
  for (double f = o.min_rate_hz; f <= o.max_rate_hz + 1e-12; f += step) {
    int h = 0;
    const double b = best_at(f, h);
    if (b < best_bic) {
      best_bic = b;
      best_f = f;
      best_n = h;
    }
  }
  if (best_n == 0) {
    throw std::invalid_argument("harmonic fit: the sampling rate (" + std::to_string(fs) +
                                " Hz) is too low for the requested harmonics");
  }
  // A multiple of the found rate that explains nearly as much with proportionally fewer
  // harmonics is the true fundamental (heart-rate variability lets a sub-harmonic's
  // extra terms absorb beat-to-beat differences).
  if (o.harmonics == 0) {
    const Eigen::Map<const Eigen::VectorXd> y(x_mm, static_cast<Eigen::Index>(n));
    const double tss = (y.array() - y.mean()).square().sum();
    const double explained = tss - NestedRss(w, best_f, best_n, o.trend_order).back();
    for (int m = 3; m >= 2; --m) {
      const int fewer = std::max(1, best_n / m);
      double f_best = 0.0;
      double rss_best = std::numeric_limits<double>::infinity();
      for (double f = m * best_f - m * step; f <= m * best_f + m * step + 1e-12; f += step / 2.0) {
        if (f > o.max_rate_hz || allowed(f) < fewer) continue;
        const double rss = NestedRss(w, f, fewer, o.trend_order).back();
        if (rss < rss_best) {
          rss_best = rss;
          f_best = f;
        }
      }
      if (f_best > 0.0 && tss - rss_best >= 0.95 * explained) {
        best_f = f_best;
        best_n = fewer;
        break;
      }
    }
  }
  // Golden-section refinement of the rate at the chosen harmonic count.
  auto rss_at = [&](double f) { return NestedRss(w, f, best_n, o.trend_order).back(); };
  double lo = std::max(o.min_rate_hz, best_f - step);
  double hi = std::min(o.max_rate_hz, best_f + step);
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  double a = hi - g * (hi - lo);
  double b = lo + g * (hi - lo);
  double fa = rss_at(a);
  double fb = rss_at(b);
  for (int it = 0; it < 30; ++it) {
    if (fa < fb) {
      hi = b;
      b = a;
      fb = fa;
      a = hi - g * (hi - lo);
      fa = rss_at(a);
    } else {
      lo = a;
      a = b;
      fa = fb;
      b = lo + g * (hi - lo);
      fb = rss_at(b);
    }
  }
  const double mid = 0.5 * (lo + hi);
  const double f = rss_at(mid) <= rss_at(best_f) ? mid : best_f;
  if (o.shape_window_beats <= 0.0)
    return FitHarmonicsAtRate(t_s, x_mm, n, t_ref_s, f, best_n, o.trend_order);

  // Harmonic count and noise from the newest beats.
  std::size_t first = n;
  while (first > 0 && t_s[n - 1] - t_s[first - 1] <= o.shape_window_beats / f) --first;
  const Window recent{t_s + first, x_mm + first, n - first, t_ref_s};
  int shape_n = best_n;
  double noise_rss = rss_at(f);
  std::size_t noise_n = n;
  if (o.harmonics == 0) {
    // A short window: at most a linear trend, so the polynomial cannot take the beat.
    const int recent_order = std::min(o.trend_order, 1);
    const int recent_base = BaseColumns(recent_order);
    int k = std::min(allowed(f), o.max_harmonics);
    while (k > 0 && static_cast<std::size_t>(2 * (recent_base + 2 * k)) > recent.n) --k;
    if (k >= 1) {
      const std::vector<double> rss = NestedRss(recent, f, k, recent_order);
      double best = std::numeric_limits<double>::infinity();
      for (int h = 1; h <= k; ++h) {
        const double b =
            Bic(rss[static_cast<std::size_t>(h - 1)], recent.n, recent_base + 2 * h + 1);
        if (b < best) {
          best = b;
          shape_n = h;
          noise_rss = rss[static_cast<std::size_t>(h - 1)];
          noise_n = recent.n;
        }
      }
    }
  }
  HarmonicFit fit = FitHarmonicsAtRate(t_s, x_mm, n, t_ref_s, f, shape_n, o.trend_order);
  if (noise_n == recent.n) {
    const auto dof = static_cast<double>(noise_n) - (std::min(o.trend_order, 1) + 1 + 2 * shape_n);
    fit.noise_mm = std::sqrt(noise_rss / std::max(dof, 1.0));
  }
  return fit;
}

}  // namespace echoservo::estimation
