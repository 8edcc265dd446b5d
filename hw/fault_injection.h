// Fault injection for hardware: a HardwareInterface that wraps another one (the simulated
// catheter, a rig) and corrupts what passes through it on a schedule — the sensor faults
// a servo must survive. It mirrors the inner interface's state and command interfaces
// (same names, units and order) and its lifecycle.
//
// Faults, each on one named interface over [start_s, end_s): NaN, ±inf, drop-out (frozen at
// the last good reading), offset, or a slow read (read() takes `value` ms of wall time,
// busy, and passes the reading unchanged: a slow driver or bus, which makes the servo's
// cycles overrun); read() applies the state faults, write() the command faults. Every corrupted
// sample is counted (injected()). Units: those of the interfaces; t in s. Errors:
// std::invalid_argument for an interface the inner hardware lacks or end_s < start_s. Details:
// docs/faults.md#the-fault-injecting-hardware-hwfault_injectionh
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "hw/hardware_interface.h"

namespace echoservo::hw {

enum class FaultKind { kNaN, kPosInf, kNegInf, kDropout, kOffset, kSlowRead };

inline constexpr double kMaxSlowReadMs = 1000.0;  // the longest slow read (kSlowRead)

struct InjectedFault {
  std::string interface;  // a state (or command) interface name of the inner hardware
  bool command = false;   // a command interface (applied on write) instead of a state
  FaultKind kind = FaultKind::kNaN;
  double start_s = 0.0, end_s = 0.0;
  double value = 0.0;  // kOffset: the offset; kSlowRead: ms, (0, kMaxSlowReadMs]
};

class FaultInjectingHardware final : public HardwareInterface {
 public:
  // `inner` must outlive this and be unconfigured or already active (then this is
  // configured and activated to match). Throws std::invalid_argument for a fault on an
  // interface the inner hardware lacks, with end_s < start_s, or a slow read outside
  // (0, kMaxSlowReadMs] ms.
  FaultInjectingHardware(HardwareInterface& inner, std::vector<InjectedFault> faults);

  std::uint64_t injected() const { return injected_; }

 protected:
  void DoConfigure() override;
  void DoActivate() override;
  void DoDeactivate() override;
  void DoCleanup() override;
  void DoRead(double t_s, double dt_s) override;
  void DoWrite(double t_s, double dt_s) override;

 private:
  double Apply(const InjectedFault& f, double value, double& last_good);

  HardwareInterface& inner_;
  std::vector<InjectedFault> faults_;
  std::vector<std::size_t> index_;  // each fault's interface index
  std::vector<double> last_good_;   // each fault's last uncorrupted value (drop-outs)
  std::uint64_t injected_ = 0;
};

}  // namespace echoservo::hw
