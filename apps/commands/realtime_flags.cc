#include "apps/commands/realtime_flags.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "hw/hardware_interface.h"

namespace echoservo::apps {

void AddRealtimeFlags(CLI::App& cmd, RealtimeFlags& f) {
  cmd.add_flag("--no-realtime", f.no_realtime,
               "run the servo thread as an ordinary thread (no SCHED_FIFO, no locked memory)");
  cmd.add_option("--rt-priority", f.priority,
                 "the servo thread's SCHED_FIFO priority (default 80; the system's range, 1–99 "
                 "on Linux)");
  cmd.add_option("--servo-cpu", f.servo_cpu, "pin the servo thread to this CPU (default: none)");
  cmd.add_flag("--no-mlock", f.no_mlock, "do not lock the process's memory (mlockall)");
  cmd.add_option("--cpu-latency-us", f.cpu_latency_us,
                 "while the servo runs, keep every CPU out of idle states slower to leave than "
                 "this, µs (PM QoS, /dev/cpu_dma_latency; default 0; -1: not requested)");
  cmd.add_option("--deadline-hold-after", f.hold_after,
                 "hold the tip after this many consecutive overrun cycles (default 10)");
  cmd.add_option("--deadline-retract-after-ms", f.retract_after_ms,
                 "retract when no cycle has ended on time for this long, ms (default 50)");
  cmd.add_option("--deadline-resume-after", f.resume_after,
                 "on-time cycles that end a deadline hold (default 50)");
  cmd.add_option("--inject-slow-read", f.slow_reads,
                 "FROM_S,TO_S,MS: the hardware read takes MS ms in the cycles of [FROM_S, TO_S) "
                 "(provokes the deadline watchdog; repeatable)");
}

control::RealtimeOptions ToRealtimeOptions(const RealtimeFlags& f) {
  control::RealtimeOptions o;
  o.enabled = !f.no_realtime;
  o.fifo_priority = f.priority;
  o.cpu = f.servo_cpu;
  o.lock_memory = !f.no_mlock;
  o.cpu_latency_us = f.cpu_latency_us;
  o.Validate();
  return o;
}

control::DeadlineWatchdogConfig ToWatchdogConfig(const RealtimeFlags& f, double period_s) {
  control::DeadlineWatchdogConfig c;
  c.hold_after_overruns = f.hold_after;
  c.retract_after_s = f.retract_after_ms / 1000.0;
  c.resume_after_on_time = f.resume_after;
  c.Validate(period_s);
  return c;
}

std::vector<hw::InjectedFault> ToSlowReads(const RealtimeFlags& f) {
  std::vector<hw::InjectedFault> out;
  for (const std::string& text : f.slow_reads) {
    std::istringstream in(text);
    double v[3];
    char c1 = 0, c2 = 0;
    std::string rest;
    if (!(in >> v[0] >> c1 >> v[1] >> c2 >> v[2]) || c1 != ',' || c2 != ',' || (in >> rest) ||
        !std::isfinite(v[0]) || !std::isfinite(v[1]) || v[0] < 0.0 || !(v[1] > v[0]) ||
        !(v[2] > 0.0) || v[2] > hw::kMaxSlowReadMs) {
      throw std::invalid_argument(
          "--inject-slow-read '" + text +
          "': expected FROM_S,TO_S,MS with 0 ≤ FROM_S < TO_S and 0 < MS ≤ 1000 (e.g. 2,2.02,3)");
    }
    hw::InjectedFault fault;
    fault.interface = std::string(hw::iface::kBasePosition);
    fault.kind = hw::FaultKind::kSlowRead;
    fault.start_s = v[0];
    fault.end_s = v[1];
    fault.value = v[2];
    out.push_back(fault);
  }
  return out;
}

}  // namespace echoservo::apps
