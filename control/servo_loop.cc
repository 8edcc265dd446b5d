#include "control/servo_loop.h"

#include <chrono>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <thread>

namespace echoservo::control {

void ServoConfig::Validate() const {
  if (!(std::isfinite(period_s) && period_s >= 1e-5 && period_s <= 0.1)) {
    throw std::invalid_argument("servo: 'period_s' must be in [1e-5, 0.1] s");
  }
  pid.Validate();
  limits.Validate();
  feedforward.Validate();
}

ServoLoop::ServoLoop(hw::HardwareInterface& hardware, ServoConfig config)
    : hw_(hardware),
      config_((config.Validate(), config)),
      pid_(config_.pid, config_.period_s),
      limiter_(config_.limits, config_.period_s),
      i_base_(hardware.StateIndex(hw::iface::kBasePosition)),
      i_tip_(hardware.StateIndex(hw::iface::kTipPosition)),
      i_force_(hardware.StateIndex(hw::iface::kSensorForce)),
      c_force_(hardware.CommandIndex(hw::iface::kActuatorForce)) {}

void ServoLoop::Start(double t_s) {
  hw_.read(t_s, config_.period_s);
  const double base = hw_.state(i_base_);
  pid_.Reset(base);
  limiter_.Reset(base);
  last_velocity_mm_s_ = 0.0;
}

CycleRecord ServoLoop::Cycle(double t_s, std::size_t cycle, const Trajectory& reference,
                             BacklashCompensator& compensator) {
  const double dt = config_.period_s;
  hw_.read(t_s, dt);
  const double base = hw_.state(i_base_);
  const double tip = hw_.state(i_tip_);
  if (!std::isfinite(base) || !std::isfinite(tip)) {
    // A sensor fault: no control action on a reading that is not a number — the actuator
    // goes passive (0 N) for this cycle, the PID, limiter and compensator keep their state.
    ++sensor_faults_;
    hw_.set_command(c_force_, 0.0);
    hw_.write(t_s, dt);
    CycleRecord r;
    r.t_s = t_s;
    r.reference_mm = reference.Evaluate(t_s).position_mm;
    r.base_cmd_mm = limiter_.setpoint_mm();
    r.base_mm = base;
    r.tip_mm = tip;
    r.force_n = hw_.state(i_force_);
    r.sensor_fault = true;
    return r;
  }

  const BaseCommand target = compensator.Calc({.t_s = t_s,
                                               .cycle = cycle,
                                               .period_s = dt,
                                               .reference = &reference,
                                               .tip_measured_mm = tip});
  const double setpoint = limiter_.Setpoint(target.position_mm, target.velocity_mm_s);
  const double velocity = limiter_.setpoint_velocity_mm_s();
  const double acceleration = (velocity - last_velocity_mm_s_) / dt;
  last_velocity_mm_s_ = velocity;
  const double feedforward = config_.feedforward.ForceN(velocity, acceleration);
  const double force = limiter_.Force(pid_.Update(setpoint, base, feedforward));
  hw_.set_command(c_force_, force);
  hw_.write(t_s, dt);

  CycleRecord r;
  r.t_s = t_s;
  r.reference_mm = reference.Evaluate(t_s).position_mm;
  r.base_cmd_mm = setpoint;
  r.base_mm = base;
  r.tip_mm = tip;
  r.force_n = hw_.state(i_force_);
  r.actuator_force_n = force;
  return r;
}

std::vector<CycleRecord> RunFixedStep(ServoLoop& loop, const Trajectory& reference,
                                      BacklashCompensator& compensator, double duration_s) {
  if (!(std::isfinite(duration_s) && duration_s > 0.0 && duration_s <= 3600.0)) {
    throw std::invalid_argument("servo run: duration must be in (0, 3600] s");
  }
  const double dt = loop.config().period_s;
  const auto cycles = static_cast<std::size_t>(std::llround(duration_s / dt));
  std::vector<CycleRecord> records;
  records.reserve(cycles);
  compensator.Reset();
  loop.Start(0.0);
  for (std::size_t k = 0; k < cycles; ++k) {
    records.push_back(loop.Cycle(static_cast<double>(k) * dt, k, reference, compensator));
  }
  return records;
}

}  // namespace echoservo::control
