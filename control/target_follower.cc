#include "control/target_follower.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace echoservo::control {
namespace {

bool Finite(const estimation::FourierMotion& m) {
  auto ok = [](double x) { return std::isfinite(x); };
  if (!(ok(m.t0_s) && ok(m.phase0_rad) && ok(m.frequency_hz) && ok(m.offset_mm) &&
        ok(m.drift_mm_s)) ||
      std::isnan(m.valid_until_s))
    return false;
  return std::all_of(m.cos_mm.begin(), m.cos_mm.end(), ok) &&
         std::all_of(m.sin_mm.begin(), m.sin_mm.end(), ok);
}

}  // namespace

void FollowerConfig::Validate() const {
  auto bad = [](const std::string& f, const std::string& why) {
    throw std::invalid_argument("FollowerConfig: " + f + " " + why);
  };
  if (!(standoff_mm >= 0 && standoff_mm <= 30)) bad("standoff_mm", "must be in [0, 30] mm");
  if (!(stale_after_s > 0 && stale_after_s <= 5)) bad("stale_after_s", "must be in (0, 5] s");
  if (!(retract_after_s >= 0 && retract_after_s <= 30))
    bad("retract_after_s", "must be in [0, 30] s");
  if (!(retract_mm >= 0 && retract_mm <= 50)) bad("retract_mm", "must be in [0, 50] mm");
  if (!(retract_speed_mm_s > 0 && retract_speed_mm_s <= 500))
    bad("retract_speed_mm_s", "must be in (0, 500] mm/s");
  if (!(std::isfinite(travel_min_mm) && std::isfinite(travel_max_mm) &&
        travel_min_mm < travel_max_mm))
    bad("travel_min_mm/travel_max_mm", "must be finite with min < max");
  if (!(offset_gain > 0 && offset_gain <= 1)) bad("offset_gain", "must be in (0, 1]");
  if (!(min_confidence >= 0 && min_confidence <= 1)) bad("min_confidence", "must be in [0, 1]");
  if (!(max_future_s >= 0 && max_future_s <= 1)) bad("max_future_s", "must be in [0, 1] s");
  if (!(scale_gain > 0 && scale_gain <= 1)) bad("scale_gain", "must be in (0, 1]");
  if (!(scale_prior_sd > 0 && scale_prior_sd <= 1)) bad("scale_prior_sd", "must be in (0, 1]");
  if (!(tip_noise_mm > 0 && tip_noise_mm <= 10)) bad("tip_noise_mm", "must be in (0, 10] mm");
}

std::string ToString(FollowerMode mode) {
  switch (mode) {
    case FollowerMode::kDisabled:
      return "disabled";
    case FollowerMode::kFollowing:
      return "following";
    case FollowerMode::kHolding:
      return "holding";
    case FollowerMode::kRetracting:
      return "retracting";
    case FollowerMode::kStopped:
      return "stopped";
  }
  return "unknown";
}

TargetFollower::TargetFollower(FollowerConfig config) : config_(config) { config_.Validate(); }

void TargetFollower::Enable(double now_s) {
  faults_ &= ~(follower_fault::kStopRequested | follower_fault::kRetracted);
  if (has_estimate_ && now_s - last_estimate_s_ <= config_.stale_after_s) {
    mode_ = FollowerMode::kFollowing;
  } else {
    Hold(now_s, 0);
  }
}

void TargetFollower::Stop(double now_s) {
  Hold(now_s, follower_fault::kStopRequested);
  mode_ = FollowerMode::kStopped;
}

void TargetFollower::SetStandoff(double standoff_mm) {
  if (!(standoff_mm >= 0 && standoff_mm <= 30))
    throw std::invalid_argument("TargetFollower: standoff must be in [0, 30] mm, got " +
                                std::to_string(standoff_mm));
  config_.standoff_mm = standoff_mm;
}

double TargetFollower::TipAt(double t_s) const {
  if (tip_history_.empty()) return tip_mm_;
  if (t_s <= tip_history_.front().first) return tip_history_.front().second;
  if (t_s >= tip_history_.back().first) return tip_history_.back().second;
  const auto hi =
      std::lower_bound(tip_history_.begin(), tip_history_.end(), t_s,
                       [](const std::pair<double, double>& p, double t) { return p.first < t; });
  const auto lo = hi - 1;
  const double f = (t_s - lo->first) / std::max(1e-12, hi->first - lo->first);
  return lo->second + f * (hi->second - lo->second);
}

bool TargetFollower::Accept(const TargetEstimateInput& e, double now_s) {
  if (!(std::isfinite(e.acquired_s) && std::isfinite(e.published_s) &&
        std::isfinite(e.tip_axis_mm) && std::isfinite(e.confidence) && Finite(e.target_motion))) {
    ++counters_.rejected_non_finite;
    faults_ |= follower_fault::kRejectedEstimate;
    return false;
  }
  const auto& m = e.target_motion;
  const bool range_ok =
      std::abs(e.tip_axis_mm) <= 1000 && std::abs(m.offset_mm) <= 1000 && m.frequency_hz > 0 &&
      m.frequency_hz <= 10 && m.cos_mm.size() == m.sin_mm.size() && m.cos_mm.size() <= 32 &&
      e.confidence >= 0 && e.confidence <= 1 &&
      std::all_of(m.cos_mm.begin(), m.cos_mm.end(), [](double a) { return std::abs(a) <= 100; }) &&
      std::all_of(m.sin_mm.begin(), m.sin_mm.end(), [](double a) { return std::abs(a) <= 100; });
  if (!range_ok) {
    ++counters_.rejected_range;
    faults_ |= follower_fault::kRejectedEstimate;
    return false;
  }
  if (e.acquired_s > e.published_s || e.published_s > now_s + config_.max_future_s ||
      now_s - e.acquired_s > config_.stale_after_s + 1.0 ||
      (has_estimate_ && e.acquired_s <= estimate_.acquired_s)) {
    ++counters_.rejected_time;
    faults_ |= follower_fault::kRejectedEstimate;
    return false;
  }
  if (e.confidence < config_.min_confidence) {
    ++counters_.rejected_confidence;
    return false;
  }
  const double x = TipAt(e.acquired_s);
  if (config_.estimate_scale) {
    // Exponentially weighted least squares of s_tip on x_tip, the slope pulled towards 1 by
    // its prior: slope = (cov + λ)/(var + λ), λ = σ_tip²/(n_eff·σ_k²), n_eff = (2 − g)/g the
    // weighted window's effective number of volumes.
    const double g = config_.scale_gain;
    if (!offset_known_) {
      mean_x_ = x;
      mean_s_ = e.tip_axis_mm;
    } else {
      const double dx = x - mean_x_, ds = e.tip_axis_mm - mean_s_;
      mean_x_ += g * dx;
      mean_s_ += g * ds;
      var_x_ = (1 - g) * (var_x_ + g * dx * dx);
      cov_xs_ = (1 - g) * (cov_xs_ + g * dx * ds);
    }
    const double n_eff = (2 - g) / g;
    const double lambda = config_.tip_noise_mm * config_.tip_noise_mm /
                          (n_eff * config_.scale_prior_sd * config_.scale_prior_sd);
    const double k_max = 4 * config_.scale_prior_sd;
    scale_ = std::clamp((cov_xs_ + lambda) / (var_x_ + lambda), 1 - k_max, 1 + k_max);
    scale_ = std::max(scale_, 0.1);
  }
  const double measured_offset = e.tip_axis_mm - scale_ * x;
  offset_mm_ = offset_known_ ? offset_mm_ + config_.offset_gain * (measured_offset - offset_mm_)
                             : measured_offset;
  offset_known_ = true;
  estimate_ = e;
  has_estimate_ = true;
  last_estimate_s_ = now_s;
  ++counters_.accepted;
  faults_ &= ~(follower_fault::kStaleEstimate | follower_fault::kRejectedEstimate);
  if (mode_ == FollowerMode::kHolding && !(faults_ & follower_fault::kStopRequested))
    mode_ = FollowerMode::kFollowing;
  return true;
}

void TargetFollower::Hold(double now_s, std::uint32_t fault) {
  if (mode_ != FollowerMode::kHolding && mode_ != FollowerMode::kRetracting &&
      mode_ != FollowerMode::kStopped) {
    hold_mm_ = tip_mm_;
    hold_since_s_ = now_s;
  }
  faults_ |= fault;
  if (mode_ != FollowerMode::kStopped && mode_ != FollowerMode::kRetracting)
    mode_ = FollowerMode::kHolding;
}

void TargetFollower::Update(double now_s, double tip_mm) {
  tip_mm_ = tip_mm;
  tip_history_.emplace_back(now_s, tip_mm);
  while (tip_history_.size() > 2 && tip_history_.front().first < now_s - 1.0)
    tip_history_.pop_front();
  if (mode_ == FollowerMode::kDisabled || mode_ == FollowerMode::kStopped) {
    if (mode_ == FollowerMode::kDisabled) hold_mm_ = tip_mm;
    return;
  }
  const bool stale = !has_estimate_ || now_s - last_estimate_s_ > config_.stale_after_s ||
                     !estimate_.target_motion.ValidAt(now_s);
  if (mode_ == FollowerMode::kFollowing && stale) {
    ++counters_.stale_events;
    Hold(now_s, follower_fault::kStaleEstimate);
  }
  if (mode_ == FollowerMode::kHolding && now_s - hold_since_s_ >= config_.retract_after_s) {
    mode_ = FollowerMode::kRetracting;
    faults_ |= follower_fault::kRetracted;
  }
}

MotionSample TargetFollower::Clamp(MotionSample m) const {
  if (m.position_mm < config_.travel_min_mm || m.position_mm > config_.travel_max_mm) {
    faults_ |= follower_fault::kTravelLimit;
    m.position_mm = std::clamp(m.position_mm, config_.travel_min_mm, config_.travel_max_mm);
    m.velocity_mm_s = 0.0;
    m.acceleration_mm_s2 = 0.0;
  }
  return m;
}

MotionSample TargetFollower::Evaluate(double t_s) const {
  MotionSample m;
  switch (mode_) {
    case FollowerMode::kFollowing: {
      // Image mm → catheter mm: x = (s − c)/k.
      const auto s = estimate_.target_motion.Evaluate(t_s);
      m.position_mm = (s.position_mm - config_.standoff_mm - offset_mm_) / scale_;
      m.velocity_mm_s = s.velocity_mm_s / scale_;
      m.acceleration_mm_s2 = s.acceleration_mm_s2 / scale_;
      break;
    }
    case FollowerMode::kRetracting: {
      const double travel = std::min(
          config_.retract_mm, config_.retract_speed_mm_s *
                                  std::max(0.0, t_s - hold_since_s_ - config_.retract_after_s));
      m.position_mm = hold_mm_ - travel;
      m.velocity_mm_s = travel < config_.retract_mm ? -config_.retract_speed_mm_s : 0.0;
      break;
    }
    case FollowerMode::kDisabled:
    case FollowerMode::kHolding:
    case FollowerMode::kStopped:
      m.position_mm = hold_mm_;
      break;
  }
  return Clamp(m);
}

}  // namespace echoservo::control
