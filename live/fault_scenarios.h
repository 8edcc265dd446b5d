// Fault injection on the servo side of the live pipeline, in simulated time (deterministic,
// faster than real time): the servo node (live/servo_node.h) on the simulated catheter
// wrapped in hw::FaultInjectingHardware, fed 25 vol/s target estimates of a known heartbeat
// motion (60 ms delay, the tip seen where the catheter is), while one fault class is
// injected per scenario — the tracker gone, NaN/inf/out-of-range/stale/future estimates,
// packet loss and delay, NaN/inf/frozen/spiking sensors, bad commands. For each, the
// result counts the faults injected, those the servo detected (rejections, sensor faults,
// stale events), the cycles that commanded outside a limit (must be 0), and whether and
// when the servo reached its safe state (holding, retracting or stopped) where the fault
// calls for one. `echoservo faults` prints them; tests/apps assert them. Units: mm, s.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace echoservo::live {

struct FaultScenarioResult {
  std::string name;
  std::string fault;           // what was injected, in words
  std::uint64_t injected = 0;  // faults injected (samples, cycles or messages)
  std::uint64_t detected = 0;  // rejected estimates/commands, sensor-fault cycles, stale events
  std::uint64_t limit_violations = 0;
  std::uint64_t cycles = 0;
  bool safe_state_required = false;
  bool safe_state_reached = false;
  double safe_state_after_s = -1.0;  // from the fault's start; < 0: not reached
  std::string final_mode;
  double tracking_rms_mm = 0.0;  // tip − setpoint while tracking, outside the fault window
};

// Every scenario, in order; `seed` drives the random loss/delay.
std::vector<FaultScenarioResult> RunFaultScenarios(std::uint64_t seed = 1);

}  // namespace echoservo::live
