#include "control/target_follower.h"

#include <algorithm>
#include <cmath>
#include <limits>
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
  params::kStandoffMm.Check(standoff_mm, "FollowerConfig");
  params::kStaleAfterS.Check(stale_after_s, "FollowerConfig");
  if (!(retract_after_s >= 0 && retract_after_s <= 30))
    bad("retract_after_s", "must be in [0, 30] s");
  if (!(retract_mm >= 0 && retract_mm <= 50)) bad("retract_mm", "must be in [0, 50] mm");
  if (!(retract_speed_mm_s > 0 && retract_speed_mm_s <= 500))
    bad("retract_speed_mm_s", "must be in (0, 500] mm/s");
  if (!(std::isfinite(travel_min_mm) && std::isfinite(travel_max_mm) &&
        travel_min_mm < travel_max_mm))
    bad("travel_min_mm/travel_max_mm", "must be finite with min < max");
  params::kOffsetGain.Check(offset_gain, "FollowerConfig");
  params::kMinConfidence.Check(min_confidence, "FollowerConfig");
  if (!(max_future_s >= 0 && max_future_s <= 1)) bad("max_future_s", "must be in [0, 1] s");
  if (!(scale_gain > 0 && scale_gain <= 1)) bad("scale_gain", "must be in (0, 1]");
  if (!(scale_prior_sd > 0 && scale_prior_sd <= 1)) bad("scale_prior_sd", "must be in (0, 1]");
  if (!(tip_noise_mm > 0 && tip_noise_mm <= 10)) bad("tip_noise_mm", "must be in (0, 10] mm");
  if (!(max_offset_change_mm > 0 && max_offset_change_mm <= 100))
    bad("max_offset_change_mm", "must be in (0, 100] mm");
  if (!(response_window_s > 0 && response_window_s <= 10))
    bad("response_window_s", "must be in (0, 10] s");
  if (!(response_delay_s >= 0 && response_delay_s <= 0.5))
    bad("response_delay_s", "must be in [0, 0.5] s");
  if (!(response_min_excitation_mm > 0 && response_min_excitation_mm <= 10))
    bad("response_min_excitation_mm", "must be in (0, 10] mm");
  if (!(response_max_gain_se > 0 && response_max_gain_se <= 1))
    bad("response_max_gain_se", "must be in (0, 1]");
  if (!(response_min_volumes >= 3 && response_min_volumes <= 10000))
    bad("response_min_volumes", "must be in [3, 10000]");
  if (!(response_min_gain >= 0 && response_min_gain < 1))
    bad("response_min_gain", "must be in [0, 1)");
  if (!(history_capacity >= 16 && history_capacity <= 1000000))
    bad("history_capacity", "must be in [16, 1000000] samples");
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

TargetFollower::TargetFollower(FollowerConfig config) : config_(config) {
  config_.Validate();
  tip_ring_.resize(config_.history_capacity);
  response_ring_.resize(256);
}

void TargetFollower::Enable(double now_s) {
  if (faults_ & fault::kImageNotResponding) {
    // The operator re-arms the check: judged afresh on volumes from now on.
    response_head_ = response_count_ = 0;
    response_ = {};
  }
  faults_ &= ~(fault::kStopRequested | fault::kRetracted | fault::kImageNotResponding |
               fault::kDeadlineHold | fault::kDeadlineRetract);
  if (has_estimate_ && now_s - last_estimate_s_ <= config_.stale_after_s) {
    mode_ = FollowerMode::kFollowing;
  } else {
    Hold(now_s, 0);
  }
}

void TargetFollower::Stop(double now_s) {
  Hold(now_s, fault::kStopRequested);
  mode_ = FollowerMode::kStopped;
}

void TargetFollower::SetStandoff(double standoff_mm) {
  if (!(standoff_mm >= 0 && standoff_mm <= 30))
    throw std::invalid_argument("TargetFollower: standoff must be in [0, 30] mm, got " +
                                std::to_string(standoff_mm));
  config_.standoff_mm = standoff_mm;
}

double TargetFollower::TipAt(double t_s) const {
  if (tip_count_ == 0) return tip_mm_;
  const auto& front = TipSample(0);
  const auto& back = TipSample(tip_count_ - 1);
  if (t_s <= front.first) return front.second;
  if (t_s >= back.first) return back.second;
  // The first sample at or after t_s (lower bound): front < t_s ≤ back, so 0 < hi < count.
  std::size_t lo_i = 0, hi_i = tip_count_ - 1;
  while (hi_i - lo_i > 1) {
    const std::size_t mid = lo_i + (hi_i - lo_i) / 2;
    if (TipSample(mid).first < t_s) {
      lo_i = mid;
    } else {
      hi_i = mid;
    }
  }
  const auto& lo = TipSample(hi_i - 1);
  const auto& hi = TipSample(hi_i);
  const double f = (t_s - lo.first) / std::max(1e-12, hi.first - lo.first);
  return lo.second + f * (hi.second - lo.second);
}

bool TargetFollower::Accept(const TargetEstimateInput& e, double now_s) {
  if (!(std::isfinite(e.acquired_s) && std::isfinite(e.published_s) &&
        std::isfinite(e.tip_axis_mm) && std::isfinite(e.confidence) && Finite(e.target_motion))) {
    ++counters_.rejected_non_finite;
    faults_ |= fault::kInvalidEstimate;
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
    faults_ |= fault::kInvalidEstimate;
    return false;
  }
  if (e.acquired_s > e.published_s || e.published_s > now_s + config_.max_future_s ||
      now_s - e.acquired_s > config_.stale_after_s + 1.0 ||
      (has_estimate_ && e.acquired_s <= estimate_.acquired_s)) {
    ++counters_.rejected_time;
    faults_ |= fault::kInvalidEstimate;
    return false;
  }
  if (e.confidence < config_.min_confidence) {
    ++counters_.rejected_confidence;
    return false;
  }
  const double x = TipAt(e.acquired_s);
  const bool frozen = faults_ & fault::kImageNotResponding;
  if (config_.estimate_scale && !frozen) {
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
  if (!offset_known_) {
    offset_mm_ = offset_anchor_mm_ = measured_offset;
  } else if (!frozen) {
    // A registration does not wander: c stays within max_offset_change_mm of its first value.
    const double c = offset_mm_ + config_.offset_gain * (measured_offset - offset_mm_);
    offset_mm_ = std::clamp(c, offset_anchor_mm_ - config_.max_offset_change_mm,
                            offset_anchor_mm_ + config_.max_offset_change_mm);
    if (offset_mm_ != c) ++counters_.offset_bounded;
  }
  offset_known_ = true;
  estimate_ = e;
  has_estimate_ = true;
  last_estimate_s_ = now_s;
  ++counters_.accepted;
  faults_ &= ~(fault::kStaleEstimate | fault::kInvalidEstimate);
  if (mode_ == FollowerMode::kHolding &&
      !(faults_ & (fault::kStopRequested | fault::kImageNotResponding | fault::kDeadlineHold)))
    mode_ = FollowerMode::kFollowing;
  if (config_.check_response) CheckResponse(e.acquired_s, e.tip_axis_mm, now_s);
  return true;
}

void TargetFollower::PushResponse(const ResponsePoint& p) {
  if (response_count_ == response_ring_.size()) {
    // Full: twice the room, oldest first (allocates; only while windows keep growing).
    std::vector<ResponsePoint> grown(2 * response_ring_.size());
    for (std::size_t i = 0; i < response_count_; ++i) grown[i] = ResponseAt(i);
    response_ring_.swap(grown);
    response_head_ = 0;
  }
  response_ring_[(response_head_ + response_count_) % response_ring_.size()] = p;
  ++response_count_;
}

void TargetFollower::CheckResponse(double acquired_s, double tip_axis_mm, double now_s) {
  PushResponse({acquired_s, TipAt(acquired_s - config_.response_delay_s), tip_axis_mm});
  while (response_count_ > 0 && ResponseAt(0).acquired_s < acquired_s - config_.response_window_s) {
    response_head_ = (response_head_ + 1) % response_ring_.size();
    --response_count_;
  }
  // Least squares of s on x over the window (two passes: the means, then the sums).
  const auto n = static_cast<double>(response_count_);
  double mx = 0.0, ms = 0.0;
  for (std::size_t i = 0; i < response_count_; ++i) {
    const ResponsePoint& p = ResponseAt(i);
    mx += p.tip_x_mm;
    ms += p.tip_s_mm;
  }
  mx /= n;
  ms /= n;
  double sxx = 0.0, sss = 0.0, sxs = 0.0;
  for (std::size_t i = 0; i < response_count_; ++i) {
    const ResponsePoint& p = ResponseAt(i);
    const double dx = p.tip_x_mm - mx, ds = p.tip_s_mm - ms;
    sxx += dx * dx;
    sss += ds * ds;
    sxs += dx * ds;
  }
  ResponseCheck& r = response_;
  r.volumes = response_count_;
  r.excitation_mm = std::sqrt(sxx / n);
  r.gain = sxx > 0 ? sxs / sxx : 0.0;
  r.gain_se =
      sxx > 0 ? config_.tip_noise_mm / std::sqrt(sxx) : std::numeric_limits<double>::infinity();
  r.correlation = sxx > 0 && sss > 0 ? sxs / std::sqrt(sxx * sss) : 0.0;
  // No verdict while the catheter barely moves: the slope's error must be small against the
  // gap between a responding image (k ≈ 1) and the threshold.
  r.judged = r.volumes >= config_.response_min_volumes &&
             r.excitation_mm >= config_.response_min_excitation_mm &&
             r.gain_se <= config_.response_max_gain_se;
  if (mode_ == FollowerMode::kFollowing && r.judged && r.gain < config_.response_min_gain &&
      !(faults_ & fault::kImageNotResponding)) {
    ++counters_.image_not_responding_events;
    Hold(now_s, fault::kImageNotResponding);
  }
}

void TargetFollower::Hold(double now_s, std::uint32_t fault) {
  if (mode_ != FollowerMode::kHolding && mode_ != FollowerMode::kRetracting &&
      mode_ != FollowerMode::kStopped) {
    // A tip a hair past a travel end (it followed a clamped reference) holds at that end:
    // holding is not a clamp.
    hold_mm_ = std::clamp(tip_mm_, config_.travel_min_mm, config_.travel_max_mm);
    hold_since_s_ = now_s;
  }
  faults_ |= fault;
  if (mode_ != FollowerMode::kStopped && mode_ != FollowerMode::kRetracting)
    mode_ = FollowerMode::kHolding;
}

void TargetFollower::DeadlineHold(double now_s) {
  if (mode_ == FollowerMode::kDisabled) {
    faults_ |= fault::kDeadlineHold;
    return;
  }
  Hold(now_s, fault::kDeadlineHold);
}

void TargetFollower::DeadlineCleared(double now_s) {
  if (!(faults_ & fault::kDeadlineHold)) return;
  faults_ &= ~fault::kDeadlineHold;
  if (mode_ != FollowerMode::kHolding ||
      (faults_ & (fault::kStopRequested | fault::kImageNotResponding)))
    return;
  const bool stale = !has_estimate_ || now_s - last_estimate_s_ > config_.stale_after_s ||
                     !estimate_.target_motion.ValidAt(now_s);
  if (!stale) {
    mode_ = FollowerMode::kFollowing;
  } else if (has_estimate_ && !(faults_ & fault::kStaleEstimate)) {
    // The estimate went stale during the hold: the hold goes on for that reason (and
    // retracts at retract_after_s from its start, as any hold).
    ++counters_.stale_events;
    faults_ |= fault::kStaleEstimate;
  }
}

void TargetFollower::DeadlineRetract(double now_s) {
  faults_ |= fault::kDeadlineRetract;
  faults_ &= ~fault::kDeadlineHold;
  if (mode_ == FollowerMode::kDisabled || mode_ == FollowerMode::kStopped ||
      mode_ == FollowerMode::kRetracting)
    return;
  Hold(now_s, 0);  // from following: hold_mm_ = the tip now
  // The retract motion (Raw) starts retract_after_s after hold_since_s_: now.
  hold_since_s_ = std::min(hold_since_s_, now_s - config_.retract_after_s);
  mode_ = FollowerMode::kRetracting;
}

void TargetFollower::Update(double now_s, double tip_mm) {
  tip_mm_ = tip_mm;
  // The ring keeps the newest history_capacity samples; older ones than 1 s are dropped (the
  // newest two always stay).
  const std::size_t capacity = tip_ring_.size();
  if (tip_count_ == capacity) {
    tip_head_ = (tip_head_ + 1) % capacity;
    --tip_count_;
  }
  tip_ring_[(tip_head_ + tip_count_) % capacity] = {now_s, tip_mm};
  ++tip_count_;
  while (tip_count_ > 2 && TipSample(0).first < now_s - 1.0) {
    tip_head_ = (tip_head_ + 1) % capacity;
    --tip_count_;
  }
  if (mode_ == FollowerMode::kDisabled) hold_mm_ = tip_mm;
  if (mode_ != FollowerMode::kDisabled && mode_ != FollowerMode::kStopped) {
    const bool stale = !has_estimate_ || now_s - last_estimate_s_ > config_.stale_after_s ||
                       !estimate_.target_motion.ValidAt(now_s);
    if (mode_ == FollowerMode::kFollowing && stale) {
      ++counters_.stale_events;
      Hold(now_s, fault::kStaleEstimate);
    }
    if (mode_ == FollowerMode::kHolding && now_s - hold_since_s_ >= config_.retract_after_s) {
      mode_ = FollowerMode::kRetracting;
      faults_ |= fault::kRetracted;
    }
  }
  // The travel bit says whether the reference lies outside travel now (Evaluate sets it too).
  const double x = Raw(now_s).position_mm;
  reference_clamped_ = !(x >= config_.travel_min_mm && x <= config_.travel_max_mm);
  if (reference_clamped_) {
    faults_ |= fault::kTravelLimit;
  } else {
    faults_ &= ~fault::kTravelLimit;
  }
}

MotionSample TargetFollower::Clamp(MotionSample m) const {
  if (m.position_mm < config_.travel_min_mm || m.position_mm > config_.travel_max_mm) {
    faults_ |= fault::kTravelLimit;
    m.position_mm = std::clamp(m.position_mm, config_.travel_min_mm, config_.travel_max_mm);
    m.velocity_mm_s = 0.0;
    m.acceleration_mm_s2 = 0.0;
  }
  return m;
}

MotionSample TargetFollower::Evaluate(double t_s) const { return Clamp(Raw(t_s)); }

MotionSample TargetFollower::Raw(double t_s) const {
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
      // Back by retract_mm, or to the travel end if that is nearer: a retraction is not a clamp.
      const double distance = std::clamp(hold_mm_ - config_.travel_min_mm, 0.0, config_.retract_mm);
      const double travel =
          std::min(distance, config_.retract_speed_mm_s *
                                 std::max(0.0, t_s - hold_since_s_ - config_.retract_after_s));
      m.position_mm = hold_mm_ - travel;
      m.velocity_mm_s = travel < distance ? -config_.retract_speed_mm_s : 0.0;
      break;
    }
    case FollowerMode::kDisabled:
    case FollowerMode::kHolding:
    case FollowerMode::kStopped:
      m.position_mm = hold_mm_;
      break;
  }
  return m;
}

}  // namespace echoservo::control
