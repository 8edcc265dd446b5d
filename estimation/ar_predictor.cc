#include "estimation/ar_predictor.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace echoservo::estimation {
namespace {

constexpr double kClipSigma = 3.0;          // a-priori errors clipped at this many robust σ
constexpr double kMeanAbsToSigma = 1.2533;  // σ = √(π/2)·E|e| for Gaussian errors

bool ArPositive(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

ArPredictor::ArPredictor(ArPredictorOptions options) : o_(options) {
  const bool ok = std::isfinite(o_.horizon_s) && o_.horizon_s >= 0.0 && ArPositive(o_.history_s) &&
                  o_.min_order >= 2 && o_.max_order >= o_.min_order && o_.max_order < kMaxParams &&
                  ArPositive(o_.memory_s) && ArPositive(o_.prior_var) &&
                  std::isfinite(o_.margin_fraction) && o_.margin_fraction >= 0.0 &&
                  ArPositive(o_.range_window_s) && std::isfinite(o_.warmup_factor) &&
                  o_.warmup_factor >= 1.0 && ArPositive(o_.max_weight_sum);
  if (!ok) {
    throw std::invalid_argument(
        "autoregressive predictor: horizon >= 0, history, memory, prior, range window and "
        "weight bound > 0, 2 <= min_order <= max_order < 64, margin >= 0, warm-up >= 1");
  }
}

void ArPredictor::Configure() {
  const double rate = 1.0 / dt_s_;
  order_ =
      std::clamp(static_cast<int>(std::lround(o_.history_s * rate)), o_.min_order, o_.max_order);
  h_ = std::max(1, static_cast<int>(std::lround(o_.horizon_s * rate)));
  // Memory at least a few times the parameters, so the solution is never under-determined.
  const double memory = std::max(o_.memory_s * rate, 4.0 * order_);
  lambda_ = 1.0 - 1.0 / memory;
  keep_ = std::max<std::size_t>(static_cast<std::size_t>(order_ + h_ + 1),
                                static_cast<std::size_t>(std::ceil(o_.range_window_s * rate)));
  ResetWeights();
}

void ArPredictor::ResetWeights() {
  w_.setZero(order_);
  p_ = o_.prior_var * Matrix::Identity(order_, order_);
  trained_ = 0;
  abs_err_ = 0.0;
}

bool ArPredictor::ready() const {
  return order_ > 0 && x_.size() >= static_cast<std::size_t>(order_) &&
         static_cast<double>(trained_) >= o_.warmup_factor * order_;
}

void ArPredictor::Regressors(std::size_t j, Vector& u) const {
  assert(j + 1 >= static_cast<std::size_t>(order_));
  u.resize(order_);
  u(0) = 1.0;
  for (int i = 1; i < order_; ++i) u(i) = x_[j - static_cast<std::size_t>(i)] - x_[j];
}

void ArPredictor::Train() {
  // The newest complete pair: regressors at n − h, target x[n] − x[n − h].
  const std::size_t n = x_.size() - 1;
  const std::size_t h = static_cast<std::size_t>(h_);
  if (x_.size() < static_cast<std::size_t>(order_) + h) return;
  const std::size_t j = n - h;
  Vector u;
  Regressors(j, u);
  const double d = x_[n] - x_[j];
  double e = d - w_.dot(u);
  // Robust: clip the a-priori error (outliers, heavy tails) once the scale is known.
  if (trained_ > static_cast<std::size_t>(order_)) {
    const double clip = kClipSigma * kMeanAbsToSigma * abs_err_;
    if (clip > 0.0) e = std::clamp(e, -clip, clip);
  }
  const double gain_weight = trained_ == 0 ? 1.0 : 1.0 - lambda_;
  abs_err_ +=
      std::max(gain_weight, 1.0 / static_cast<double>(trained_ + 1)) * (std::abs(e) - abs_err_);
  const Vector pu = p_ * u;
  const double s = lambda_ + u.dot(pu);
  const Vector k = pu / s;
  w_ += k * e;
  p_.noalias() -= k * pu.transpose();
  p_ /= lambda_;
  // Regularisation against wind-up (forgetting with little excitation inflates P): keep
  // P below its prior, i.e. never less ridge than the prior's.
  const double cap = o_.prior_var * order_;
  const double trace = p_.trace();
  if (trace > cap) p_ *= cap / trace;
  if (trained_ % 64 == 0) p_ = 0.5 * (p_ + p_.transpose()).eval();
  ++trained_;
  if (!w_.allFinite() || w_.tail(order_ - 1).lpNorm<1>() > o_.max_weight_sum || !p_.allFinite()) {
    ++resets_;
    ResetWeights();
  }
}

void ArPredictor::Refresh() {
  const double newest = x_.back();
  predicted_mm_ = newest;
  if (!ready()) return;
  Vector u;
  Regressors(x_.size() - 1, u);
  const double y = newest + w_.dot(u);
  predicted_mm_ = ClampToRecentRange(
      x_, static_cast<std::size_t>(std::ceil(o_.range_window_s / dt_s_)), o_.margin_fraction, y);
}

void ArPredictor::Update(double t_s, double z) {
  const auto configure = [this] {
    dt_s_ = grid_.dt_s();
    Configure();
  };
  if (!AppendOnGrid(grid_, t_s, z, x_, keep_, counters_, configure, [this] { Train(); })) {
    predicted_mm_ = z;
    return;
  }
  Refresh();
}

double ArPredictor::Predict(double t_s) const {
  const double newest = x_.empty() ? 0.0 : x_.back();
  return TowardsHorizon(newest, predicted_mm_, grid_.last_t_s(), dt_s_ > 0.0 ? h_ * dt_s_ : 0.0,
                        t_s);
}

}  // namespace echoservo::estimation
