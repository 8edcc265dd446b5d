#include "estimation/ar_predictor.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace echoservo::estimation {
namespace {

constexpr std::size_t kRateIntervals = 8;  // intervals whose median sets the rate
constexpr double kIrregularHigh = 1.6;     // an interval beyond this × nominal: reset history
constexpr double kIrregularLow = 0.4;      // below this × nominal: reset history
constexpr long kMaxFilled = 3;             // dropped samples filled by interpolation

// Online, a candidate predicts once it has this many rows per parameter and this many
// a-priori scores: the a-priori error itself guards against over-fitting (the offline
// reference, with no such guard, asks for kArRowsPerParameter).
constexpr double kOnlineRowsPerParameter = 3.0;
constexpr std::size_t kMinScored = 10;

bool ArPositive(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

struct ArPredictor::Solver {
  Eigen::LLT<Matrix> llt;
  Matrix a;
};

ArPredictor::ArPredictor(ArPredictorOptions options)
    : o_(options), solver_(std::make_unique<Solver>()) {
  const bool ok =
      std::isfinite(o_.horizon_s) && o_.horizon_s >= 0.0 && ArPositive(o_.max_history_s) &&
      ArPositive(o_.max_lag_rate_hz) && ArPositive(o_.memory_s) && ArPositive(o_.validation_s) &&
      ArPositive(o_.refit_s) && ArPositive(o_.ridge) && std::isfinite(o_.margin_fraction) &&
      o_.margin_fraction >= 0.0 && ArPositive(o_.range_window_s) && ArPositive(o_.max_weight_sum);
  if (!ok) {
    throw std::invalid_argument(
        "autoregressive predictor: horizon >= 0; history, lag rate, memory, validation, "
        "refit interval, ridge, range window and weight bound > 0; margin >= 0");
  }
}

ArPredictor::~ArPredictor() = default;

void ArPredictor::Configure() {
  const double rate = 1.0 / dt_s_;
  stride_ = std::max(1, static_cast<int>(std::ceil(rate / o_.max_lag_rate_hz - 1e-9)));
  const int by_history = 1 + static_cast<int>(std::floor(o_.max_history_s * rate / stride_ + 1e-9));
  candidates_.clear();
  for (int p : kArCandidateOrders)
    if (p <= std::min(by_history, kMaxParams)) candidates_.push_back({p, Vector(), false, 0.0, 0});
  width_ = candidates_.back().order;
  h_steps_ = o_.horizon_s * rate;
  h_ceil_ = std::max(1, static_cast<int>(std::ceil(h_steps_ - 1e-9)));
  lambda_ = 1.0 - 1.0 / std::max(o_.memory_s * rate, 4.0 * width_);
  alpha_ = std::min(1.0, 1.0 / (o_.validation_s * rate));
  refit_every_ = std::max(1, static_cast<int>(std::lround(o_.refit_s * rate)));
  keep_ = std::max<std::size_t>(static_cast<std::size_t>((width_ - 1) * stride_ + h_ceil_ + 1),
                                static_cast<std::size_t>(std::ceil(o_.range_window_s * rate)));
  ResetLearning();
}

void ArPredictor::ResetLearning() {
  g_.setZero(width_, width_);
  b_.setZero(width_);
  rows_ = 0.0;
  learned_ = 0;
  since_refit_ = 0;
  largest_used_ = 0;
  ++generation_;
  for (Candidate& c : candidates_) {
    c.w.setZero(c.order);
    c.solved = false;
    c.mse = 0.0;
    c.scored = 0;
  }
}

int ArPredictor::Best() const {
  int best = -1;
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    const Candidate& c = candidates_[i];
    if (!c.solved || c.scored < kMinScored || rows_ < kOnlineRowsPerParameter * c.order) continue;
    if (best < 0 || c.mse < candidates_[static_cast<std::size_t>(best)].mse)
      best = static_cast<int>(i);
  }
  return best;
}

int ArPredictor::order() const {
  const int best = Best();
  return best < 0 ? 0 : candidates_[static_cast<std::size_t>(best)].order;
}

double ArPredictor::recent_mse_mm2() const {
  const int best = Best();
  return best < 0 ? 0.0 : candidates_[static_cast<std::size_t>(best)].mse;
}

bool ArPredictor::ready() const {
  const int p = order();
  return p > 0 && x_.size() > static_cast<std::size_t>((p - 1) * stride_);
}

void ArPredictor::Regressors(std::size_t j, int p, Vector& u) const {
  assert(j >= static_cast<std::size_t>((p - 1) * stride_));
  u.resize(p);
  u(0) = 1.0;
  for (int i = 1; i < p; ++i) u(i) = x_[j - static_cast<std::size_t>(i * stride_)] - x_[j];
}

void ArPredictor::Learn() {
  // The row the newest sample completes: regressors at j = n − ⌈h⌉, the target the samples
  // interpolated at j + h.
  const std::size_t n = x_.size() - 1;
  const std::size_t reach = static_cast<std::size_t>((width_ - 1) * stride_ + h_ceil_);
  if (n < reach) return;
  const std::size_t j = n - static_cast<std::size_t>(h_ceil_);
  const double at = static_cast<double>(j) + h_steps_;
  const auto below = std::min(static_cast<std::size_t>(std::floor(at)), n);
  const std::size_t above = std::min(below + 1, n);
  const double frac = at - static_cast<double>(below);
  const double target = x_[below] + frac * (x_[above] - x_[below]);
  Vector u;
  Regressors(j, width_, u);
  // Every solved candidate's a-priori error on this row, before it learns it.
  const double y = target - x_[j];
  for (Candidate& c : candidates_) {
    if (!c.solved) continue;
    const double e = y - c.w.dot(u.head(c.order));
    const double w = std::max(alpha_, 1.0 / static_cast<double>(c.scored + 1));
    c.mse += w * (e * e - c.mse);
    ++c.scored;
  }
  g_ *= lambda_;
  b_ *= lambda_;
  g_.selfadjointView<Eigen::Lower>().rankUpdate(u);
  b_ += u * y;
  rows_ = lambda_ * rows_ + 1.0;
  ++learned_;
  if (++since_refit_ >= refit_every_) Refit();
}

void ArPredictor::Refit() {
  since_refit_ = 0;

  const double ridge = o_.ridge * std::max(g_.diagonal().mean(), 1e-12);
  for (Candidate& c : candidates_) {
    if (rows_ < 2.0 * c.order) continue;  // under-determined yet
    Matrix& a = solver_->a;
    a = g_.topLeftCorner(c.order, c.order).selfadjointView<Eigen::Lower>();
    a.diagonal().array() += ridge;
    solver_->llt.compute(a);
    if (solver_->llt.info() != Eigen::Success) continue;
    const Vector w = solver_->llt.solve(b_.head(c.order));
    if (!w.allFinite() || w.tail(c.order - 1).lpNorm<1>() > o_.max_weight_sum) {
      // Ill-conditioned at this order (too many lags for what the motion excites): this
      // candidate sits out until a refit solves it well; the others go on.
      c.solved = false;
      ++resets_;
      continue;
    }
    c.w = w;
    c.solved = true;
  }
}

void ArPredictor::Refresh() {
  const double newest = x_.back();
  predicted_mm_ = newest;
  if (!ready()) return;
  const Candidate& c = candidates_[static_cast<std::size_t>(Best())];
  if (c.order > largest_used_) {
    largest_used_ = c.order;
    ++generation_;
  }
  Vector u;
  Regressors(x_.size() - 1, c.order, u);
  const double y = newest + c.w.dot(u);
  const std::size_t span =
      std::min(x_.size(), static_cast<std::size_t>(std::ceil(o_.range_window_s / dt_s_)));
  const auto [lo, hi] = std::minmax_element(x_.end() - static_cast<std::ptrdiff_t>(span), x_.end());
  const double margin = o_.margin_fraction * (*hi - *lo);
  predicted_mm_ = std::isfinite(y) ? std::clamp(y, *lo - margin, *hi + margin) : newest;
}

void ArPredictor::Update(double t_s, double z) {
  if (!std::isfinite(t_s) || !std::isfinite(z)) {
    throw std::invalid_argument(
        "autoregressive predictor: a measurement or its time is NaN or "
        "infinite");
  }
  if (any_ && !(t_s > t_)) {
    throw std::invalid_argument(
        "autoregressive predictor: measurement times must be strictly increasing");
  }
  if (any_) {
    const double dt = t_s - t_;
    if (dt_s_ == 0.0) {
      intervals_.push_back(dt);
      if (intervals_.size() >= kRateIntervals) {
        std::vector<double> v(intervals_.begin(), intervals_.end());
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        dt_s_ = v[v.size() / 2];
        Configure();
      }
    } else if (dt > kIrregularHigh * dt_s_ || dt < kIrregularLow * dt_s_) {
      const double steps = dt / dt_s_;
      const long k = std::lround(steps);
      if (k >= 2 && k <= kMaxFilled + 1 && std::abs(steps - static_cast<double>(k)) < 0.3 &&
          !x_.empty()) {
        // One to kMaxFilled dropped samples on the grid: fill them by linear interpolation.
        const double from = x_.back();
        for (long i = 1; i < k; ++i) {
          x_.push_back(from + (z - from) * static_cast<double>(i) / static_cast<double>(k));
          while (x_.size() > keep_) x_.pop_front();
          Learn();
        }
        ++filled_;
      } else {
        // A gap or an irregular interval: the lags no longer mean the same delays.
        x_.clear();
        ++history_resets_;
      }
    }
  }
  any_ = true;
  t_ = t_s;
  x_.push_back(z);
  if (dt_s_ == 0.0) {
    while (x_.size() > kRateIntervals + 1) x_.pop_front();
    predicted_mm_ = z;
    return;
  }
  while (x_.size() > keep_) x_.pop_front();
  Learn();
  Refresh();
}

double ArPredictor::Predict(double t_s) const {
  const double newest = x_.empty() ? 0.0 : x_.back();
  const double dt = t_s - t_;
  if (!(dt > 0.0) || dt_s_ == 0.0 || o_.horizon_s <= 0.0) return newest;
  const double frac = std::min(1.0, dt / o_.horizon_s);
  return newest + frac * (predicted_mm_ - newest);
}

}  // namespace echoservo::estimation
