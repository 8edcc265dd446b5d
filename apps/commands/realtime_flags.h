// The servo's real-time command-line flags, shared by `servo` and `demo`: SCHED_FIFO on or
// off and its priority, the CPU to pin the servo thread to, locked memory, the deadline
// watchdog's limits, and slow hardware reads injected on purpose to provoke it
// (control/realtime.h, control/deadline_watchdog.h, hw/fault_injection.h; docs/control.md
// "Real-time execution", "Missed deadlines").
#pragma once

#include <string>
#include <vector>

#include "control/deadline_watchdog.h"
#include "control/realtime.h"
#include "hw/fault_injection.h"

namespace CLI {
class App;
}

namespace echoservo::apps {

struct RealtimeFlags {
  bool no_realtime = false;
  int priority = 80;
  int servo_cpu = -1;
  bool no_mlock = false;
  int cpu_latency_us = 0;
  int hold_after = 10;
  double retract_after_ms = 50.0;
  int resume_after = 50;
  std::vector<std::string> slow_reads;  // FROM_S,TO_S,MS
};

void AddRealtimeFlags(CLI::App& cmd, RealtimeFlags& flags);
// Throw std::invalid_argument naming the flag.
control::RealtimeOptions ToRealtimeOptions(const RealtimeFlags& flags);
control::DeadlineWatchdogConfig ToWatchdogConfig(const RealtimeFlags& flags, double period_s);
// --inject-slow-read FROM_S,TO_S,MS: the hardware's read() takes MS ms of busy wall time in
// cycles whose time lies in [FROM_S, TO_S) (on the base-position interface).
std::vector<hw::InjectedFault> ToSlowReads(const RealtimeFlags& flags);

}  // namespace echoservo::apps
