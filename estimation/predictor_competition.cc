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

// w·EKF + (1 − w)·AR (least squares); the competition sets w (Blend).
class EkfArBlend final : public MotionPredictor {
 public:
  EkfArBlend(const HeartbeatEkf& ekf, const LsArPredictor& ar) : ekf_(ekf), ar_(ar) {}
  std::string name() const override { return "ekf_ar_blend"; }
  void Update(double, double) override {}  // its members learn on their own
  double Predict(double t_s) const override {
    if (!(ekf_weight < 1.0)) return ekf_.Predict(t_s);
    if (!(ekf_weight > 0.0)) return ar_.Predict(t_s);
    return ekf_weight * ekf_.Predict(t_s) + (1.0 - ekf_weight) * ar_.Predict(t_s);
  }
  double ekf_weight = std::numeric_limits<double>::quiet_NaN();  // NaN: no record yet

 private:
  const HeartbeatEkf& ekf_;
  const LsArPredictor& ar_;
};

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
  o_.ls_ar.horizon_s = o_.latency_s;
  auto ekf = std::make_unique<HeartbeatEkf>(o_.ekf);
  auto ar = std::make_unique<ArPredictor>(o_.ar);
  auto ls_ar = std::make_unique<LsArPredictor>(o_.ls_ar);
  auto blend = std::make_unique<EkfArBlend>(*ekf, *ls_ar);
  ekf_ = ekf.get();
  ar_ = ar.get();
  ls_ar_ = ls_ar.get();
  blend_ = blend.get();
  predictors_.push_back(std::move(ekf));
  predictors_.push_back(std::move(ar));
  predictors_.push_back(std::move(ls_ar));
  predictors_.push_back(std::move(blend));
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
    // The EKF's and the least-squares AR's joint error moments (the blend's weight).
    if (!std::isnan(p.predicted_mm[kEkf]) && !std::isnan(p.predicted_mm[kArLs])) {
      const double ee = p.predicted_mm[kEkf] - ref;
      const double ea = p.predicted_mm[kArLs] - ref;
      const double w = std::max(alpha, 1.0 / static_cast<double>(pair_scored_ + 1));
      pair_[0] += w * (ee * ee - pair_[0]);
      pair_[1] += w * (ea * ea - pair_[1]);
      pair_[2] += w * (ee * ea - pair_[2]);
      ++pair_scored_;
    }
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

void PredictorCompetition::Restart(int i) {
  const auto u = static_cast<std::size_t>(i);
  status_[u].scored = 0;
  status_[u].recent_rms_mm = 0.0;
  mse_[u] = 0.0;
  for (Pending& p : pending_) p.predicted_mm[i] = std::numeric_limits<double>::quiet_NaN();
  if (i == kEkf) {  // the blend's record and weight restart with the EKF
    pair_scored_ = 0;
    Restart(kBlend);
  }
}

void PredictorCompetition::Blend() {
  // The convex weight on the EKF minimising the pair's recent mean squared error (errors
  // correlated: Bates & Granger with the covariance); none before the pair has a first
  // record. While a restarted record (a new AR order, a new EKF) builds up, the previous
  // weight stays: falling back to the EKF alone cost up to 35 % on the real phantom, where
  // the EKF is 1.4–2.1× the reference.
  if (pair_scored_ < PairRecord()) return;
  const double denom = pair_[0] + pair_[1] - 2.0 * pair_[2];
  blend_->ekf_weight =
      denom > kMseFloor ? std::clamp((pair_[1] - pair_[2]) / denom, 0.0, 1.0) : 1.0;
}

std::size_t PredictorCompetition::PairRecord() const {
  const double half_window = typical_dt_s_ > 0.0 ? 0.5 * o_.window_s / typical_dt_s_ : 0.0;
  return std::max(static_cast<std::size_t>(o_.min_scored), static_cast<std::size_t>(half_window));
}

double PredictorCompetition::blend_ekf_weight() const { return blend_->ekf_weight; }

void PredictorCompetition::Choose() {
  int best = -1;
  for (int i = 0; i < kCount; ++i) {
    if (i == kArLs) continue;  // it drives the output through the blend (the EKF's shape)
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
    Restart(kEkf);
  }
  // When a more flexible least-squares AR order takes over, its record so far is that of the
  // simpler orders it outgrew: it takes the new order's own a-priori error (out of sample,
  // at the same horizon) instead, and the blend's record restarts.
  if (ls_ar_->generation() != ls_ar_generation_) {
    ls_ar_generation_ = ls_ar_->generation();
    const std::size_t scored = status_[kArLs].scored;
    Restart(kArLs);
    pair_scored_ = 0;  // the pair's moments restart with the new model (the blend's record stays)
    if (ls_ar_->ready()) {
      mse_[kArLs] = ls_ar_->recent_mse_mm2();
      status_[kArLs].scored = scored;
      status_[kArLs].recent_rms_mm = std::sqrt(mse_[kArLs]);
    }
  }
  any_ = true;
  t_ = t_s;
  z_ = z;
  Blend();
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
  // Once the least-squares AR has predicted, its holds (after a gap broke its history) are
  // scored too: they are what it ships then.
  ls_ar_trained_ = ls_ar_trained_ || ls_ar_->ready();
  if (!ls_ar_trained_) p.predicted_mm[kArLs] = std::numeric_limits<double>::quiet_NaN();
  if (!ekf_->initialised() || !ls_ar_trained_ || std::isnan(blend_->ekf_weight))
    p.predicted_mm[kBlend] = std::numeric_limits<double>::quiet_NaN();
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
  if (o_.combination == Combination::kPickBest && chosen_ == kBlend && ekf_->initialised()) {
    // The heartbeat's shape from the EKF, shifted to the blend's prediction at the latency.
    m = ekf_->Motion();
    const double at = t_ + o_.latency_s;
    m.offset_mm += blend_->Predict(at) - ekf_->Predict(at);
    return m;
  }
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
