#include "estimation/ls_ar_predictor.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace echoservo::estimation {
namespace {

// Online, a candidate predicts once it has as many rows per parameter as the offline
// reference asks for and this many a-priori scores: with 3 rows per parameter (its a-priori
// error as the only guard) its first seconds were poorer than the recursive AR's, and it
// drove the demo's output then (docs/predictor.md, issue 32).
constexpr double kOnlineRowsPerParameter = kArRowsPerParameter;
constexpr std::size_t kMinScored = 10;

bool LsArPositive(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

struct LsArPredictor::Solver {
  Eigen::LLT<Matrix> llt;
  Matrix a;
};

LsArPredictor::LsArPredictor(LsArPredictorOptions options)
    : o_(options), solver_(std::make_unique<Solver>()) {
  const bool ok = std::isfinite(o_.horizon_s) && o_.horizon_s >= 0.0 &&
                  LsArPositive(o_.max_history_s) && LsArPositive(o_.max_lag_rate_hz) &&
                  LsArPositive(o_.memory_s) && LsArPositive(o_.validation_s) &&
                  LsArPositive(o_.refit_s) && LsArPositive(o_.ridge) &&
                  std::isfinite(o_.margin_fraction) && o_.margin_fraction >= 0.0 &&
                  LsArPositive(o_.range_window_s) && LsArPositive(o_.max_weight_sum);
  if (!ok) {
    throw std::invalid_argument(
        "least-squares autoregressive predictor: horizon >= 0; history, lag rate, memory, "
        "validation, "
        "refit interval, ridge, range window and weight bound > 0; margin >= 0");
  }
}

LsArPredictor::~LsArPredictor() = default;

void LsArPredictor::Configure() {
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

void LsArPredictor::ResetLearning() {
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

int LsArPredictor::Best() const {
  int best = -1;
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    const Candidate& c = candidates_[i];
    if (!c.solved || c.scored < kMinScored || rows_ < kOnlineRowsPerParameter * c.order) continue;
    if (best < 0 || c.mse < candidates_[static_cast<std::size_t>(best)].mse)
      best = static_cast<int>(i);
  }
  return best;
}

int LsArPredictor::order() const {
  const int best = Best();
  return best < 0 ? 0 : candidates_[static_cast<std::size_t>(best)].order;
}

double LsArPredictor::recent_mse_mm2() const {
  const int best = Best();
  return best < 0 ? 0.0 : candidates_[static_cast<std::size_t>(best)].mse;
}

bool LsArPredictor::ready() const {
  const int p = order();
  return p > 0 && x_.size() > static_cast<std::size_t>((p - 1) * stride_);
}

void LsArPredictor::Regressors(std::size_t j, int p, Vector& u) const {
  assert(j >= static_cast<std::size_t>((p - 1) * stride_));
  u.resize(p);
  u(0) = 1.0;
  for (int i = 1; i < p; ++i) u(i) = x_[j - static_cast<std::size_t>(i * stride_)] - x_[j];
}

void LsArPredictor::Learn() {
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

void LsArPredictor::Refit() {
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

void LsArPredictor::Refresh() {
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
  predicted_mm_ = ClampToRecentRange(
      x_, static_cast<std::size_t>(std::ceil(o_.range_window_s / dt_s_)), o_.margin_fraction, y);
}

void LsArPredictor::Update(double t_s, double z) {
  const auto configure = [this] {
    dt_s_ = grid_.dt_s();
    Configure();
  };
  if (!AppendOnGrid(grid_, t_s, z, x_, keep_, counters_, configure, [this] { Learn(); })) {
    predicted_mm_ = z;
    return;
  }
  Refresh();
}

double LsArPredictor::Predict(double t_s) const {
  const double newest = x_.empty() ? 0.0 : x_.back();
  return TowardsHorizon(newest, predicted_mm_, grid_.last_t_s(), dt_s_ > 0.0 ? o_.horizon_s : 0.0,
                        t_s);
}

}  // namespace echoservo::estimation
