// The 1 kHz catheter base servo: read → compensate → limit → PID + feed-forward → write.
//
// Each cycle reads the hardware (base, tip, force), asks the backlash compensator for
// the base command that makes the tip follow the reference, shapes it through the
// safety limits (travel, velocity, acceleration), closes the PID position loop with
// friction/inertia feed-forward, clamps the force and writes it. Two clocks drive it:
// RunFixedStep (deterministic t = k·period, for simulation and tests) and the servo
// runtime (live/servo_runtime.h: the real-time cycle clock or simulated time, for every
// command, around live::ServoNode). A base or tip reading
// that is not finite is a sensor fault: that cycle commands 0 N and leaves the controller's
// state alone (counted; the supervisor above decides what happens next). Units: mm, s, N.
#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

#include "control/backlash_compensation.h"
#include "control/command_limiter.h"
#include "control/cycle_timing.h"
#include "control/friction_feedforward.h"
#include "control/pid.h"
#include "control/realtime.h"
#include "hw/hardware_interface.h"

namespace echoservo::control {

struct ServoConfig {
  double period_s = 1e-3;
  PidGains pid;
  Limits limits;
  FrictionFeedforward feedforward;  // all zeros: off
  void Validate() const;
};

// One cycle, as recorded in the trial format (base_cmd is the shaped setpoint).
struct CycleRecord {
  double t_s = 0.0;
  double reference_mm = 0.0;
  double base_cmd_mm = 0.0;
  double base_mm = 0.0;
  double tip_mm = 0.0;
  double force_n = 0.0;           // force sensor
  double actuator_force_n = 0.0;  // commanded
  bool sensor_fault = false;      // base or tip not finite: no control action, 0 N
};

class ServoLoop {
 public:
  // The hardware must outlive the loop. Throws std::invalid_argument for a bad config.
  ServoLoop(hw::HardwareInterface& hardware, ServoConfig config);
  // Samples the hardware once and resets the PID and the setpoint to the base position.
  void Start(double t_s);
  CycleRecord Cycle(double t_s, std::size_t cycle, const Trajectory& reference,
                    BacklashCompensator& compensator);
  const CommandLimiter& limiter() const { return limiter_; }
  // Cycles whose base or tip reading was not finite (actuator passive for that cycle).
  std::uint64_t sensor_faults() const { return sensor_faults_; }
  const ServoConfig& config() const { return config_; }

 private:
  hw::HardwareInterface& hw_;
  ServoConfig config_;
  Pid pid_;
  CommandLimiter limiter_;
  std::size_t i_base_, i_tip_, i_force_, c_force_;
  double last_velocity_mm_s_ = 0.0;
  std::uint64_t sensor_faults_ = 0;
};

// Runs `duration_s` on the deterministic clock starting at t = 0 (Start included).
std::vector<CycleRecord> RunFixedStep(ServoLoop& loop, const Trajectory& reference,
                                      BacklashCompensator& compensator, double duration_s);

}  // namespace echoservo::control
