// Safety limits enforced on every command the controller sends.
//
// The base setpoint (mm) is shaped so that it never leaves the travel window, never
// exceeds the velocity and acceleration limits, and decelerates in time to reach a
// target without overshoot; the actuator force (N) is clamped to ±max_force. A
// non-finite setpoint or force is rejected (the previous setpoint is held, the force
// is zeroed). Every intervention is counted by kind; travel clamps and non-finite
// inputs are faults, velocity/acceleration shaping is normal operation.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

namespace echoservo::control {

struct Limits {
  double travel_min_mm = -24.4;  // 1 mm inside the slide's end stops (±25.4 mm)
  double travel_max_mm = 24.4;
  double max_velocity_mm_s = 400.0;
  double max_acceleration_mm_s2 = 60000.0;
  double max_force_n = 26.7;
  // Throws std::invalid_argument naming the field for a non-finite, non-positive or
  // inverted limit.
  void Validate() const;
};

enum class LimitEvent : int {
  kTravel = 0,    // setpoint outside travel: clamped (fault)
  kNonFinite,     // NaN/inf setpoint or force: rejected (fault)
  kVelocity,      // setpoint velocity shaped
  kAcceleration,  // setpoint acceleration shaped
  kForce,         // force command clamped (fault)
  kCount
};
std::string_view ToString(LimitEvent e);

class CommandLimiter {
 public:
  CommandLimiter(Limits limits, double period_s);
  void Reset(double position_mm);
  // Moves the internal setpoint one period towards `target_mm` (whose own velocity
  // is `target_velocity_mm_s`), within all limits. Returns the new setpoint.
  double Setpoint(double target_mm, double target_velocity_mm_s);
  double setpoint_mm() const { return position_mm_; }
  double setpoint_velocity_mm_s() const { return velocity_mm_s_; }
  // Clamps a force command (N) to ±max_force; a non-finite force becomes 0.
  double Force(double force_n);

  std::uint64_t count(LimitEvent e) const { return counts_[static_cast<int>(e)]; }
  std::uint64_t faults() const;
  const Limits& limits() const { return limits_; }

 private:
  void Note(LimitEvent e) { ++counts_[static_cast<int>(e)]; }
  double BrakingSpeed(double distance_mm) const;
  Limits limits_;
  double period_s_;
  double position_mm_ = 0.0;
  double velocity_mm_s_ = 0.0;
  std::array<std::uint64_t, static_cast<int>(LimitEvent::kCount)> counts_{};
};

}  // namespace echoservo::control
