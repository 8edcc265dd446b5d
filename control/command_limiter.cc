#include "control/command_limiter.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace echoservo::control {

void Limits::Validate() const {
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0.0)) {
      throw std::invalid_argument(std::string("limits: '") + name + "' must be finite and > 0");
    }
  };
  if (!(std::isfinite(travel_min_mm) && std::isfinite(travel_max_mm) &&
        travel_min_mm < travel_max_mm)) {
    throw std::invalid_argument("limits: 'travel_min_mm' must be finite and below 'travel_max_mm'");
  }
  positive(max_velocity_mm_s, "max_velocity_mm_s");
  positive(max_acceleration_mm_s2, "max_acceleration_mm_s2");
  positive(max_force_n, "max_force_n");
}

std::string_view ToString(LimitEvent e) {
  switch (e) {
    case LimitEvent::kTravel:
      return "travel";
    case LimitEvent::kNonFinite:
      return "non_finite";
    case LimitEvent::kVelocity:
      return "velocity";
    case LimitEvent::kAcceleration:
      return "acceleration";
    case LimitEvent::kForce:
      return "force";
    case LimitEvent::kCount:
      break;
  }
  return "unknown";
}

CommandLimiter::CommandLimiter(Limits limits, double period_s) : limits_(limits), period_s_(period_s) {
  limits_.Validate();
  if (!(std::isfinite(period_s) && period_s > 0.0)) {
    throw std::invalid_argument("limiter: period must be finite and > 0 s");
  }
}

void CommandLimiter::Reset(double position_mm) {
  position_mm_ = std::clamp(std::isfinite(position_mm) ? position_mm : 0.0, limits_.travel_min_mm,
                            limits_.travel_max_mm);
  velocity_mm_s_ = 0.0;
}

std::uint64_t CommandLimiter::faults() const {
  return count(LimitEvent::kTravel) + count(LimitEvent::kNonFinite) + count(LimitEvent::kForce);
}

double CommandLimiter::Setpoint(double target_mm, double target_velocity_mm_s) {
  if (!std::isfinite(target_mm) || !std::isfinite(target_velocity_mm_s)) {
    Note(LimitEvent::kNonFinite);
    target_mm = position_mm_;
    target_velocity_mm_s = 0.0;
  }
  if (target_mm < limits_.travel_min_mm || target_mm > limits_.travel_max_mm) {
    Note(LimitEvent::kTravel);
    target_mm = std::clamp(target_mm, limits_.travel_min_mm, limits_.travel_max_mm);
    target_velocity_mm_s = 0.0;
  }
  const double dt = period_s_;
  const double a_max = limits_.max_acceleration_mm_s2;
  const double v_max = limits_.max_velocity_mm_s;
  // Close the gap in one period if possible, but never faster than the braking curve
  // allows (so that the setpoint arrives without overshoot), on top of the target's
  // own velocity.
  const double gap = target_mm - position_mm_;
  const double closing = std::copysign(std::min(std::abs(gap) / dt, std::sqrt(2.0 * a_max * std::abs(gap))), gap);
  double v = target_velocity_mm_s + closing;
  if (std::abs(v) > v_max) {
    Note(LimitEvent::kVelocity);
    v = std::clamp(v, -v_max, v_max);
  }
  const double dv = v - velocity_mm_s_;
  if (std::abs(dv) > a_max * dt * (1.0 + 1e-9)) {
    Note(LimitEvent::kAcceleration);
    v = velocity_mm_s_ + std::copysign(a_max * dt, dv);
  }
  // Never step beyond the travel window even while decelerating.
  const double next = std::clamp(position_mm_ + v * dt, limits_.travel_min_mm, limits_.travel_max_mm);
  velocity_mm_s_ = (next - position_mm_) / dt;
  position_mm_ = next;
  return position_mm_;
}

double CommandLimiter::Force(double force_n) {
  if (!std::isfinite(force_n)) {
    Note(LimitEvent::kNonFinite);
    return 0.0;
  }
  if (std::abs(force_n) > limits_.max_force_n) {
    Note(LimitEvent::kForce);
    return std::clamp(force_n, -limits_.max_force_n, limits_.max_force_n);
  }
  return force_n;
}

}  // namespace echoservo::control
