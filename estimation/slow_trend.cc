#include "estimation/slow_trend.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace echoservo::estimation {
namespace {

constexpr int kTrendColumns = SlowTrendWindow::kTrendOrder + 1;

}  // namespace

bool TrendEvidence::Significant() const {
  if (parameters == 0 || samples < static_cast<std::size_t>(2 * parameters)) return false;
  const auto n = static_cast<double>(samples);
  return n * std::log(rss_flat_mm2 / rss_trend_mm2) > SlowTrendWindow::kTrendOrder * std::log(n);
}

void SlowTrendWindow::Reset(int harmonics, double nominal_s) {
  if (harmonics < 1 || harmonics > kMaxHarmonics ||
      !(std::isfinite(nominal_s) && nominal_s > 0.0)) {
    throw std::invalid_argument(
        "slow trend window: harmonics must be in [1, 12] and the window length positive");
  }
  columns_ = kTrendColumns + 2 * harmonics;
  nominal_s_ = nominal_s;
  samples_ = 0;
  gram_.setZero(columns_, columns_);
  xty_.setZero(columns_);
  zz_ = 0.0;
}

void SlowTrendWindow::Add(double t_s, double phase_rad, double z_mm) {
  if (samples_ == 0) {
    first_s_ = t_s;
    z0_mm_ = z_mm;
  }
  newest_s_ = t_s;
  ++samples_;
  Vector row(columns_);
  const double u = (t_s - first_s_) / nominal_s_;
  double power = 1.0;
  for (int j = 0; j < kTrendColumns; ++j) {
    row(j) = power;
    power *= u;
  }
  const double c1 = std::cos(phase_rad);
  const double s1 = std::sin(phase_rad);
  double c = c1;
  double s = s1;
  for (int k = kTrendColumns; k < columns_; k += 2) {
    row(k) = c;
    row(k + 1) = s;
    const double next = c * c1 - s * s1;
    s = s * c1 + c * s1;
    c = next;
  }
  gram_.selfadjointView<Eigen::Upper>().rankUpdate(row);
  const double y = z_mm - z0_mm_;
  xty_ += y * row;
  zz_ += y * y;
}

TrendEvidence SlowTrendWindow::Evidence() const {
  TrendEvidence e;
  e.samples = samples_;
  e.window_s = span_s();
  if (samples_ < static_cast<std::size_t>(2 * columns_)) return e;
  e.parameters = columns_;
  const double floor = 1e-12 * zz_ + 1e-300;
  const Matrix g = gram_.selfadjointView<Eigen::Upper>();
  const Vector beta = g.ldlt().solve(xty_);
  e.rss_trend_mm2 = std::max(zz_ - beta.dot(xty_), floor);
  // The flat fit: the constant and the harmonics (columns 0 and kTrendColumns..).
  const int flat = columns_ - SlowTrendWindow::kTrendOrder;
  Matrix gf(flat, flat);
  Vector xf(flat);
  auto source = [&](int i) { return i == 0 ? 0 : i + SlowTrendWindow::kTrendOrder; };
  for (int i = 0; i < flat; ++i) {
    xf(i) = xty_(source(i));
    for (int j = 0; j < flat; ++j) gf(i, j) = g(source(i), source(j));
  }
  const Vector beta_flat = gf.ldlt().solve(xf);
  e.rss_flat_mm2 = std::max(zz_ - beta_flat.dot(xf), e.rss_trend_mm2);
  // Trend β₁u + β₂u² + β₃u³ in u = τ/T: second derivative (2β₂ + 6β₃u)/T², its mean
  // square from Σ1, Σu, Σu² (the Gram's first row); slope (β₁ + 2β₂u + 3β₃u²)/T.
  const double n = g(0, 0);
  const double b2 = beta(2);
  const double b3 = beta(3);
  const double t2 = nominal_s_ * nominal_s_;
  const double accel_ss = 4.0 * b2 * b2 * n + 24.0 * b2 * b3 * g(0, 1) + 36.0 * b3 * b3 * g(0, 2);
  e.accel_rms_mm_s2 = std::sqrt(std::max(accel_ss, 0.0) / n) / t2;
  const double un = e.window_s / nominal_s_;
  e.drift_mm_s = (beta(1) + 2.0 * b2 * un + 3.0 * b3 * un * un) / nominal_s_;
  return e;
}

}  // namespace echoservo::estimation
