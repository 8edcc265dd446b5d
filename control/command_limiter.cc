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

CommandLimiter::CommandLimiter(Limits limits, double period_s)
    : limits_(limits), period_s_(period_s) {
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

double CommandLimiter::BrakingSpeed(double distance_mm) const {
  // Largest speed v from which, slowing by a·dt every period, the setpoint moves at most
  // `distance` before it stops: dt·Σ_j max(v − j·a·dt, 0) ≤ d. With u = v/(a·dt),
  // D = d/(a·dt²) and m = ⌊u⌋ the sum is (m+1)·u − m(m+1)/2, so u = (D + m(m+1)/2)/(m+1)
  // on the branch where m ≤ u < m+1. Exact in discrete time: a setpoint at this speed
  // can always meet the next period's bound with one a·dt step of deceleration.
  const double a_dt = limits_.max_acceleration_mm_s2 * period_s_;
  const double big_d = std::max(distance_mm, 0.0) / (a_dt * period_s_);
  double m = std::floor(0.5 * (std::sqrt(1.0 + 8.0 * big_d) - 1.0));
  for (int i = 0; i < 3; ++i) {
    const double u = (big_d + 0.5 * m * (m + 1.0)) / (m + 1.0);
    if (u < m && m > 0.0) {
      m -= 1.0;
    } else if (u >= m + 1.0) {
      m += 1.0;
    } else {
      return a_dt * u;
    }
  }
  return a_dt * (big_d + 0.5 * m * (m + 1.0)) / (m + 1.0);
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
  const double a_dt = limits_.max_acceleration_mm_s2 * dt;
  const double v_max = limits_.max_velocity_mm_s;
  target_velocity_mm_s = std::clamp(target_velocity_mm_s, -v_max, v_max);

  // Land on the target this period if possible. Relative to the target's own motion,
  // approach no faster than the setpoint can still brake within the remaining gap.
  const double gap = target_mm - position_mm_;
  const double relative = gap / dt - target_velocity_mm_s;
  const double brake = BrakingSpeed(std::abs(gap - target_velocity_mm_s * dt));
  double v = target_velocity_mm_s + std::clamp(relative, -brake, brake);
  if (std::abs(v) > v_max) {
    Note(LimitEvent::kVelocity);
    v = std::clamp(v, -v_max, v_max);
  }
  const double dv = v - velocity_mm_s_;
  if (std::abs(dv) > a_dt * (1.0 + 1e-12)) {
    Note(LimitEvent::kAcceleration);
    v = velocity_mm_s_ + std::copysign(a_dt, dv);
  }
  // Never run into the travel ends: brake for them as for a target. Consistent with the
  // previous period's bound, this never asks for more than a·dt of deceleration.
  const double to_wall =
      v > 0.0 ? limits_.travel_max_mm - position_mm_ : position_mm_ - limits_.travel_min_mm;
  const double wall_speed = BrakingSpeed(to_wall);
  if (std::abs(v) > wall_speed) v = std::copysign(wall_speed, v);
  const double next =
      std::clamp(position_mm_ + v * dt, limits_.travel_min_mm, limits_.travel_max_mm);
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
