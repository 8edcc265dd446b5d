#include "estimation/predictor_competition.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "estimation/motion_trace.h"

namespace echoservo::estimation {
namespace {

constexpr double kTypicalDtGain = 0.05;  // running typical interval: ~20 measurements
constexpr int kMotionSamples = 5;        // points of the forward prediction the line fits
constexpr double kMseFloor = 1e-12;      // mm²: weights of a perfect competitor stay finite

}  // namespace

PredictorCompetition::PredictorCompetition(PredictorCompetitionOptions options)
    : o_(std::move(options)) {
  if (!(std::isfinite(o_.latency_s) && o_.latency_s >= 0.0 && o_.latency_s <= 2.0)) {
    throw std::invalid_argument("predictor competition: the latency must be in [0, 2] s");
  }
  if (!(std::isfinite(o_.window_s) && o_.window_s > 0.0 && std::isfinite(o_.hysteresis) &&
        o_.hysteresis >= 0.0 && o_.hysteresis < 1.0 && o_.min_scored >= 1)) {
    throw std::invalid_argument(
        "predictor competition: window_s must be > 0, hysteresis in [0, 1), min_scored >= 1");
  }
  o_.ar.horizon_s = o_.latency_s;
  auto ekf = std::make_unique<HeartbeatEkf>(o_.ekf);
  auto ar = std::make_unique<ArPredictor>(o_.ar);
  ekf_ = ekf.get();
  ar_ = ar.get();
  predictors_.push_back(std::move(ekf));
  predictors_.push_back(std::move(ar));
  predictors_.push_back(std::make_unique<ZeroOrderHold>());
  predictors_.push_back(std::make_unique<LinearExtrapolation>());
  predictors_.push_back(std::make_unique<ConstantVelocityKf>(o_.cv));
  for (const auto& p : predictors_) status_.push_back({p->name(), 0.0, 0, 0});
  mse_.assign(kCount, 0.0);
  weights_.assign(kCount, 0.0);
  weights_[kZoh] = 1.0;
}

void PredictorCompetition::Score(double t_s, double z) {
  const double dt = t_s - t_;
  const bool gap = typical_dt_s_ > 0.0 && dt > kGapFactor * typical_dt_s_;
  if (typical_dt_s_ == 0.0) {
    typical_dt_s_ = dt;
  } else if (!gap) {
    typical_dt_s_ += kTypicalDtGain * (dt - typical_dt_s_);
  }
  const double alpha = std::min(1.0, typical_dt_s_ / o_.window_s);
  while (!pending_.empty() && pending_.front().target_s <= t_s) {
    const Pending p = pending_.front();
    pending_.pop_front();
    if (gap) continue;  // no reference inside a gap
    const double ref = z_ + (z - z_) * (p.target_s - t_) / dt;
    for (int i = 0; i < kCount; ++i) {
      if (std::isnan(p.predicted_mm[i])) continue;  // made while it was not ready
      CompetitorStatus& s = status_[static_cast<std::size_t>(i)];
      const double e = p.predicted_mm[i] - ref;
      // A plain mean until the exponential window is full, then exponential.
      const double w = std::max(alpha, 1.0 / static_cast<double>(s.scored + 1));
      mse_[static_cast<std::size_t>(i)] += w * (e * e - mse_[static_cast<std::size_t>(i)]);
      ++s.scored;
      s.recent_rms_mm = std::sqrt(mse_[static_cast<std::size_t>(i)]);
    }
  }
}

void PredictorCompetition::Choose() {
  int best = -1;
  for (int i = 0; i < kCount; ++i) {
    if (status_[static_cast<std::size_t>(i)].scored < static_cast<std::size_t>(o_.min_scored))
      continue;
    if (best < 0 || mse_[static_cast<std::size_t>(i)] < mse_[static_cast<std::size_t>(best)])
      best = i;
  }
  if (best < 0 || best == chosen_) return;
  const bool chosen_scored =
      status_[static_cast<std::size_t>(chosen_)].scored >= static_cast<std::size_t>(o_.min_scored);
  const double keep = (1.0 - o_.hysteresis) * (1.0 - o_.hysteresis);
  if (!chosen_scored ||
      mse_[static_cast<std::size_t>(best)] < keep * mse_[static_cast<std::size_t>(chosen_)]) {
    chosen_ = best;
    ++switches_;
  }
}

void PredictorCompetition::Weigh() {
  double sum = 0.0;
  for (int i = 0; i < kCount; ++i) {
    const auto u = static_cast<std::size_t>(i);
    weights_[u] = status_[u].scored >= static_cast<std::size_t>(o_.min_scored)
                      ? 1.0 / std::max(mse_[u], kMseFloor)
                      : 0.0;
    sum += weights_[u];
  }
  if (sum == 0.0) {
    std::fill(weights_.begin(), weights_.end(), 0.0);
    weights_[kZoh] = 1.0;
    chosen_ = kZoh;
    return;
  }
  for (double& w : weights_) w /= sum;
  chosen_ = static_cast<int>(std::max_element(weights_.begin(), weights_.end()) - weights_.begin());
}

void PredictorCompetition::Update(double t_s, double z) {
  if (!std::isfinite(t_s) || !std::isfinite(z)) {
    throw std::invalid_argument(
        "predictor competition: a measurement or its time is NaN or infinite");
  }
  if (any_ && !(t_s > t_)) {
    throw std::invalid_argument(
        "predictor competition: measurement times must be strictly increasing");
  }
  if (any_) Score(t_s, z);
  for (auto& p : predictors_) p->Update(t_s, z);
  // A (re)initialised EKF starts its record afresh: what it predicted while buffering was
  // the zero-order hold, not the heartbeat model.
  if (ekf_->initialisations() != ekf_initialisations_) {
    ekf_initialisations_ = ekf_->initialisations();
    status_[kEkf].scored = 0;
    status_[kEkf].recent_rms_mm = 0.0;
    mse_[kEkf] = 0.0;
    for (Pending& p : pending_) p.predicted_mm[kEkf] = std::numeric_limits<double>::quiet_NaN();
  }
  any_ = true;
  t_ = t_s;
  z_ = z;
  if (o_.combination == Combination::kWeighted) {
    Weigh();
  } else {
    Choose();
  }
  ++status_[static_cast<std::size_t>(chosen_)].chosen;
  Pending p;
  p.target_s = t_s + o_.latency_s;
  for (int i = 0; i < kCount; ++i)
    p.predicted_mm[i] = predictors_[static_cast<std::size_t>(i)]->Predict(p.target_s);
  // Not scored while not ready (the EKF buffering, the AR predictor untrained: both hold).
  if (!ekf_->initialised()) p.predicted_mm[kEkf] = std::numeric_limits<double>::quiet_NaN();
  if (!ar_->ready()) p.predicted_mm[kAr] = std::numeric_limits<double>::quiet_NaN();
  pending_.push_back(p);
}

double PredictorCompetition::Predict(double t_s) const {
  if (o_.combination == Combination::kPickBest)
    return predictors_[static_cast<std::size_t>(chosen_)]->Predict(t_s);
  double y = 0.0;
  for (int i = 0; i < kCount; ++i) {
    const auto u = static_cast<std::size_t>(i);
    if (weights_[u] > 0.0) y += weights_[u] * predictors_[u]->Predict(t_s);
  }
  return y;
}

FourierMotion PredictorCompetition::Motion() const {
  FourierMotion m;
  if (!any_) {
    m.valid_until_s = 0.0;
    return m;
  }
  if (o_.combination == Combination::kPickBest && chosen_ == kEkf && ekf_->initialised())
    return ekf_->Motion();
  // A line through the forward prediction over [newest, newest + latency] (least squares
  // on kMotionSamples points): offset at the newest measurement, drift its slope.
  m.t0_s = t_;
  if (o_.latency_s > 0.0) {
    double st = 0.0, sy = 0.0, stt = 0.0, sty = 0.0;
    for (int k = 0; k < kMotionSamples; ++k) {
      const double tau = o_.latency_s * k / (kMotionSamples - 1);
      const double y = Predict(t_ + tau);
      st += tau;
      sy += y;
      stt += tau * tau;
      sty += tau * y;
    }
    const double n = kMotionSamples;
    m.drift_mm_s = (n * sty - st * sy) / (n * stt - st * st);
    m.offset_mm = (sy - m.drift_mm_s * st) / n;
  } else {
    m.offset_mm = Predict(t_);
  }
  m.valid_until_s = t_ + o_.ekf.horizon_s;
  return m;
}

}  // namespace echoservo::estimation
