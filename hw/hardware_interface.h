// Hardware abstraction in the ros2_control style.
//
// A HardwareInterface has a lifecycle (unconfigured → configure → inactive → activate
// → active → deactivate → inactive → cleanup → unconfigured) and, while active, is
// driven every control cycle by read(t, dt) (sample sensors into the state
// interfaces) and write(t, dt) (apply the command interfaces for [t, t + dt)). State
// and command interfaces are named "<component>/<quantity>" with units listed beside
// them; a controller looks a name up once and then uses the index at 1 kHz.
// Subclasses (the simulated catheter, a real rig) implement the protected Do* hooks.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace echoservo::hw {

enum class LifecycleState { kUnconfigured, kInactive, kActive };
std::string_view ToString(LifecycleState s);

// Standard interface names of a catheter drive.
namespace iface {
inline constexpr std::string_view kBasePosition = "base/position";        // mm
inline constexpr std::string_view kBaseVelocity = "base/velocity";        // mm/s
inline constexpr std::string_view kActuatorCurrent = "actuator/current";  // A
inline constexpr std::string_view kActuatorForce = "actuator/force";      // N (state and command)
inline constexpr std::string_view kSensorForce = "force_sensor/force";    // N
inline constexpr std::string_view kTipPosition = "tip/position";          // mm
inline constexpr std::string_view kFaultCount = "fault/count";            // count
}  // namespace iface

struct InterfaceInfo {
  std::string name;
  std::string unit;
};

class HardwareInterface {
 public:
  virtual ~HardwareInterface() = default;
  HardwareInterface(const HardwareInterface&) = delete;
  HardwareInterface& operator=(const HardwareInterface&) = delete;

  // Lifecycle transitions; each throws std::logic_error when called from the wrong state.
  void Configure();
  void Activate();
  void Deactivate();
  void Cleanup();
  LifecycleState lifecycle_state() const { return lifecycle_; }

  // Cyclic I/O; throw std::logic_error unless active. t and dt in s.
  void read(double t_s, double dt_s);
  void write(double t_s, double dt_s);

  const std::vector<InterfaceInfo>& state_interfaces() const { return state_info_; }
  const std::vector<InterfaceInfo>& command_interfaces() const { return command_info_; }
  // Throws std::invalid_argument for an unknown name.
  std::size_t StateIndex(std::string_view name) const;
  std::size_t CommandIndex(std::string_view name) const;
  double state(std::size_t index) const { return states_.at(index); }
  double state(std::string_view name) const { return states_[StateIndex(name)]; }
  void set_command(std::size_t index, double value) { commands_.at(index) = value; }
  double command(std::size_t index) const { return commands_.at(index); }

 protected:
  HardwareInterface() = default;
  std::size_t AddStateInterface(std::string name, std::string unit);
  std::size_t AddCommandInterface(std::string name, std::string unit);
  void set_state(std::size_t index, double value) { states_[index] = value; }

  virtual void DoConfigure() {}
  virtual void DoActivate() {}
  virtual void DoDeactivate() {}
  virtual void DoCleanup() {}
  virtual void DoRead(double t_s, double dt_s) = 0;
  virtual void DoWrite(double t_s, double dt_s) = 0;

 private:
  void RequireState(LifecycleState expected, std::string_view what) const;
  LifecycleState lifecycle_ = LifecycleState::kUnconfigured;
  std::vector<InterfaceInfo> state_info_;
  std::vector<InterfaceInfo> command_info_;
  std::vector<double> states_;
  std::vector<double> commands_;
};

}  // namespace echoservo::hw
