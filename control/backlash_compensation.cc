#include "control/backlash_compensation.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>

namespace echoservo::control {
namespace {

double LeadForWidth(double width_mm, double max_acceleration_mm_s2) {
  return std::sqrt(std::max(width_mm, 0.0) / max_acceleration_mm_s2);
}

}  // namespace

BaseCommand NoCompensation::DoCalc(const CompensatorInput& in) {
  const MotionSample r = in.reference->Evaluate(in.t_s);
  return {r.position_mm, r.velocity_mm_s};
}

double DirectionTracker::Update(double v, bool* switched) {
  const double before = sign_;
  if (v > threshold_) sign_ = 1.0;
  if (v < -threshold_) sign_ = -1.0;
  *switched = sign_ != before && before != 0.0;
  return sign_;
}

StaticInverse::StaticInverse(double width_mm, double max_acceleration_mm_s2, double time_advance_s)
    : width_mm_(width_mm), time_advance_s_(time_advance_s) {
  if (!(std::isfinite(width_mm) && width_mm >= 0.0)) {
    throw std::invalid_argument("static inverse: width_mm must be finite and >= 0");
  }
  if (!(std::isfinite(max_acceleration_mm_s2) && max_acceleration_mm_s2 > 0.0)) {
    throw std::invalid_argument("static inverse: max_acceleration_mm_s2 must be > 0");
  }
  if (!(std::isfinite(time_advance_s) && time_advance_s >= 0.0 && time_advance_s <= 0.1)) {
    throw std::invalid_argument("static inverse: time_advance_s must be in [0, 0.1] s");
  }
  lead_s_ = LeadForWidth(width_mm, max_acceleration_mm_s2);
}

BaseCommand StaticInverse::DoCalc(const CompensatorInput& in) {
  const MotionSample r = in.reference->Evaluate(in.t_s + time_advance_s_);
  const MotionSample ahead = in.reference->Evaluate(in.t_s + time_advance_s_ + lead_s_);
  bool switched = false;
  const double s = direction_.Update(ahead.velocity_mm_s, &switched);
  return {r.position_mm + 0.5 * s * width_mm_, r.velocity_mm_s};
}

IterativeInverse::IterativeInverse(IterativeOptions options) : options_(options) {
  if (!(std::isfinite(options.learning_gain) && options.learning_gain > 0.0 &&
        options.learning_gain <= 2.0)) {
    throw std::invalid_argument("iterative inverse: learning_gain must be in (0, 2]");
  }
}

void IterativeInverse::Learn(const std::vector<double>& tip_error_mm) {
  // Validate first: a rejected run leaves the correction table untouched.
  for (std::size_t k = 0; k < tip_error_mm.size(); ++k) {
    if (!std::isfinite(tip_error_mm[k])) {
      throw std::invalid_argument("iterative inverse: non-finite tip error at cycle " +
                                  std::to_string(k));
    }
  }
  if (correction_mm_.size() < tip_error_mm.size()) correction_mm_.resize(tip_error_mm.size(), 0.0);
  for (std::size_t k = 0; k < tip_error_mm.size(); ++k) {
    correction_mm_[k] += options_.learning_gain * tip_error_mm[k];
  }
}

BaseCommand IterativeInverse::DoCalc(const CompensatorInput& in) {
  const MotionSample r = in.reference->Evaluate(in.t_s);
  const double c = in.cycle < correction_mm_.size() ? correction_mm_[in.cycle] : 0.0;
  // The correction table is a sampled signal; its slope feeds the limiter's velocity.
  const double c_next = in.cycle + 1 < correction_mm_.size() ? correction_mm_[in.cycle + 1] : c;
  return {r.position_mm + c, r.velocity_mm_s + (c_next - c) / in.period_s};
}

void AdaptiveOptions::Validate() const {
  auto check = [](bool ok, const char* name) {
    if (!ok) throw std::invalid_argument(std::string("adaptive inverse: invalid '") + name + "'");
  };
  check(std::isfinite(initial_width_mm) && initial_width_mm >= 0.0, "initial_width_mm");
  check(std::isfinite(max_acceleration_mm_s2) && max_acceleration_mm_s2 > 0.0,
        "max_acceleration_mm_s2");
  check(forgetting > 0.9 && forgetting <= 1.0, "forgetting");
  check(std::isfinite(settle_after_reversal_s) && settle_after_reversal_s >= 0.0,
        "settle_after_reversal_s");
  check(std::isfinite(min_speed_mm_s) && min_speed_mm_s >= 0.0, "min_speed_mm_s");
  check(std::isfinite(initial_uncertainty) && initial_uncertainty > 0.0, "initial_uncertainty");
  check(std::isfinite(innovation_gate_mm) && innovation_gate_mm > 0.0, "innovation_gate_mm");
}

AdaptiveInverse::AdaptiveInverse(AdaptiveOptions options) : options_(options) {
  options_.Validate();
  Reset();
}

void AdaptiveInverse::Reset() {
  direction_.Reset();
  theta_ << options_.initial_width_mm, 0.0, 0.0;
  p_ = Eigen::Matrix3d::Zero();
  p_(0, 0) = options_.initial_uncertainty;
  p_(1, 1) = options_.initial_uncertainty * 1e-4;  // lag: (10 ms)² scale
  p_(2, 2) = options_.initial_uncertainty;
  p0_trace_ = p_.trace();
  last_switch_s_ = -1e9;
}

BaseCommand AdaptiveInverse::DoCalc(const CompensatorInput& in) {
  const MotionSample r = in.reference->Evaluate(in.t_s);
  const double lead = LeadForWidth(theta_(0), options_.max_acceleration_mm_s2);
  const MotionSample ahead = in.reference->Evaluate(in.t_s + lead);
  bool switched = false;
  const double s = direction_.Update(ahead.velocity_mm_s, &switched);
  if (switched) last_switch_s_ = in.t_s;

  // Learn from the tip error during engaged motion, away from reversals.
  const bool engaged = s != 0.0 && in.t_s - last_switch_s_ > options_.settle_after_reversal_s &&
                       std::abs(r.velocity_mm_s) > options_.min_speed_mm_s &&
                       (r.velocity_mm_s > 0.0) == (s > 0.0);
  if (engaged && std::isfinite(in.tip_measured_mm)) {
    const Eigen::Vector3d phi(0.5 * s, r.velocity_mm_s, 1.0);
    // The error is already the innovation: with the current estimates applied, a
    // perfect model leaves e = 0. Gross errors (start-up, a slip) are not learned from.
    const double error = r.position_mm - in.tip_measured_mm;
    if (std::abs(error) <= options_.innovation_gate_mm) {
      const Eigen::Vector3d p_phi = p_ * phi;
      const double denom = options_.forgetting + phi.dot(p_phi);
      const Eigen::Vector3d gain = p_phi / denom;
      theta_ += gain * error;
      p_ = (p_ - gain * p_phi.transpose()) / options_.forgetting;
      p_ = 0.5 * (p_ + p_.transpose());
      // Bound the covariance: with forgetting, directions the motion does not excite
      // grow without limit (wind-up) and the next excitation then throws the estimates.
      const double trace = p_.trace();
      if (trace > p0_trace_) p_ *= p0_trace_ / trace;
      theta_(0) = std::max(theta_(0), 0.0);
      theta_(1) = std::clamp(theta_(1), -0.1, 0.2);
    }
  }
  assert(theta_.allFinite());
  return {r.position_mm + 0.5 * s * theta_(0) + theta_(1) * r.velocity_mm_s + theta_(2),
          r.velocity_mm_s + theta_(1) * r.acceleration_mm_s2};
}

}  // namespace echoservo::control
