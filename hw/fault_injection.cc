#include "hw/fault_injection.h"

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace echoservo::hw {

FaultInjectingHardware::FaultInjectingHardware(HardwareInterface& inner,
                                               std::vector<InjectedFault> faults)
    : inner_(inner), faults_(std::move(faults)) {
  for (const InterfaceInfo& i : inner_.state_interfaces()) AddStateInterface(i.name, i.unit);
  for (const InterfaceInfo& i : inner_.command_interfaces()) AddCommandInterface(i.name, i.unit);
  for (const InjectedFault& f : faults_) {
    if (!(f.end_s >= f.start_s))
      throw std::invalid_argument("FaultInjectingHardware: fault on '" + f.interface +
                                  "' ends before it starts");
    if (f.kind == FaultKind::kSlowRead &&
        !(std::isfinite(f.value) && f.value > 0.0 && f.value <= kMaxSlowReadMs))
      throw std::invalid_argument("FaultInjectingHardware: a slow read must take (0, " +
                                  std::to_string(kMaxSlowReadMs) + "] ms, not " +
                                  std::to_string(f.value));
    index_.push_back(f.command ? inner_.CommandIndex(f.interface) : inner_.StateIndex(f.interface));
  }
  last_good_.assign(faults_.size(), 0.0);
  if (inner_.lifecycle_state() == LifecycleState::kActive) {
    Configure();
    Activate();
  } else if (inner_.lifecycle_state() != LifecycleState::kUnconfigured) {
    throw std::invalid_argument(
        "FaultInjectingHardware: the inner hardware must be unconfigured or active");
  }
}

void FaultInjectingHardware::DoConfigure() {
  if (inner_.lifecycle_state() == LifecycleState::kUnconfigured) inner_.Configure();
}
void FaultInjectingHardware::DoActivate() {
  if (inner_.lifecycle_state() == LifecycleState::kInactive) inner_.Activate();
}
void FaultInjectingHardware::DoDeactivate() { inner_.Deactivate(); }
void FaultInjectingHardware::DoCleanup() { inner_.Cleanup(); }

double FaultInjectingHardware::Apply(const InjectedFault& f, double value, double& last_good) {
  ++injected_;
  switch (f.kind) {
    case FaultKind::kNaN:
      return std::numeric_limits<double>::quiet_NaN();
    case FaultKind::kPosInf:
      return std::numeric_limits<double>::infinity();
    case FaultKind::kNegInf:
      return -std::numeric_limits<double>::infinity();
    case FaultKind::kDropout:
      return last_good;
    case FaultKind::kOffset:
      return value + f.value;
    case FaultKind::kSlowRead: {
      // Busy, as a driver waiting on its bus would be: a sleep would hand the CPU back.
      const auto until = std::chrono::steady_clock::now() +
                         std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                             std::chrono::duration<double, std::milli>(f.value));
      while (std::chrono::steady_clock::now() < until) {
      }
      return value;
    }
  }
  return value;
}

void FaultInjectingHardware::DoRead(double t_s, double dt_s) {
  inner_.read(t_s, dt_s);
  for (std::size_t i = 0; i < inner_.state_interfaces().size(); ++i) set_state(i, inner_.state(i));
  for (std::size_t k = 0; k < faults_.size(); ++k) {
    const InjectedFault& f = faults_[k];
    if (f.command) continue;
    const double v = inner_.state(index_[k]);
    if (t_s >= f.start_s && t_s < f.end_s) {
      set_state(index_[k], Apply(f, v, last_good_[k]));
    } else {
      last_good_[k] = v;
    }
  }
}

void FaultInjectingHardware::DoWrite(double t_s, double dt_s) {
  for (std::size_t i = 0; i < command_interfaces().size(); ++i) {
    double v = command(i);
    for (std::size_t k = 0; k < faults_.size(); ++k) {
      const InjectedFault& f = faults_[k];
      if (!f.command || index_[k] != i) continue;
      if (t_s >= f.start_s && t_s < f.end_s) {
        v = Apply(f, v, last_good_[k]);
      } else {
        last_good_[k] = v;
      }
    }
    inner_.set_command(i, v);
  }
  inner_.write(t_s, dt_s);
}

}  // namespace echoservo::hw
