#include "hw/hardware_interface.h"

#include <cmath>
#include <stdexcept>

namespace echoservo::hw {

std::string_view ToString(LifecycleState s) {
  switch (s) {
    case LifecycleState::kUnconfigured:
      return "unconfigured";
    case LifecycleState::kInactive:
      return "inactive";
    case LifecycleState::kActive:
      return "active";
  }
  return "unknown";
}

void HardwareInterface::RequireState(LifecycleState expected, std::string_view what) const {
  if (lifecycle_ != expected) {
    throw std::logic_error(std::string("hardware: cannot ") + std::string(what) + " while " +
                           std::string(ToString(lifecycle_)));
  }
}

void HardwareInterface::Configure() {
  RequireState(LifecycleState::kUnconfigured, "configure");
  DoConfigure();
  lifecycle_ = LifecycleState::kInactive;
}

void HardwareInterface::Activate() {
  RequireState(LifecycleState::kInactive, "activate");
  for (double& c : commands_) c = 0.0;
  DoActivate();
  lifecycle_ = LifecycleState::kActive;
}

void HardwareInterface::Deactivate() {
  RequireState(LifecycleState::kActive, "deactivate");
  DoDeactivate();
  lifecycle_ = LifecycleState::kInactive;
}

void HardwareInterface::Cleanup() {
  RequireState(LifecycleState::kInactive, "clean up");
  DoCleanup();
  lifecycle_ = LifecycleState::kUnconfigured;
}

void HardwareInterface::read(double t_s, double dt_s) {
  RequireState(LifecycleState::kActive, "read()");
  DoRead(t_s, dt_s);
}

void HardwareInterface::write(double t_s, double dt_s) {
  RequireState(LifecycleState::kActive, "write()");
  if (!(std::isfinite(dt_s) && dt_s > 0.0))
    throw std::invalid_argument("hardware: write() with dt <= 0");
  DoWrite(t_s, dt_s);
}

std::size_t HardwareInterface::AddStateInterface(std::string name, std::string unit) {
  state_info_.push_back({std::move(name), std::move(unit)});
  states_.push_back(0.0);
  return states_.size() - 1;
}

std::size_t HardwareInterface::AddCommandInterface(std::string name, std::string unit) {
  command_info_.push_back({std::move(name), std::move(unit)});
  commands_.push_back(0.0);
  return commands_.size() - 1;
}

namespace {
std::size_t Find(const std::vector<InterfaceInfo>& infos, std::string_view name, const char* kind) {
  for (std::size_t i = 0; i < infos.size(); ++i) {
    if (infos[i].name == name) return i;
  }
  throw std::invalid_argument(std::string("hardware: no ") + kind + " interface '" +
                              std::string(name) + "'");
}
}  // namespace

std::size_t HardwareInterface::StateIndex(std::string_view name) const {
  return Find(state_info_, name, "state");
}
std::size_t HardwareInterface::CommandIndex(std::string_view name) const {
  return Find(command_info_, name, "command");
}

}  // namespace echoservo::hw
