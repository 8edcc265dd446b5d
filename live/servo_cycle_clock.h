// The servo thread's cycle clock for the live nodes (`servo`, `demo`): it raises the calling
// thread to real time (control/realtime.h), sleeps until each cycle's absolute deadline on
// the pipeline clock (an absolute clock_nanosleep), times every cycle (control/cycle_timing.h:
// wake-up latency, duration, overruns) and feeds the servo node's deadline watchdog
// (control/deadline_watchdog.h) with each wake-up and each cycle's end. Cycle k is due at t = k ·
// period_s (pipeline s).
//
// Used as: `ServoCycleClock c(clock, period, &node, rt); for (k…) { t = c.Wait(k);
// node.Cycle(t, k); …bookkeeping…; c.Done(); }`. Construct it on the servo thread, after the
// other threads exist (they would inherit SCHED_FIFO otherwise); its destructor gives the
// thread back its scheduling policy and CPU set (locked memory stays locked).
// Errors: std::invalid_argument for bad real-time options (naming the option).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "control/cycle_timing.h"
#include "control/deadline_watchdog.h"
#include "control/realtime.h"
#include "live/pipeline_clock.h"

namespace echoservo::live {

class ServoNode;

class ServoCycleClock {
 public:
  // `node` may be null (no watchdog to feed). Applies `realtime` to the calling thread.
  ServoCycleClock(const PipelineClock& clock, double period_s, ServoNode* node,
                  const control::RealtimeOptions& realtime);
  ~ServoCycleClock();
  ServoCycleClock(const ServoCycleClock&) = delete;
  ServoCycleClock& operator=(const ServoCycleClock&) = delete;
  // Sleeps until cycle k's deadline and returns its time t = k · period_s.
  double Wait(std::uint64_t k);
  // The cycle's work is done (after the node's Cycle and what the caller does in the cycle).
  void Done();

  const control::RealtimeStatus& realtime() const { return status_; }
  const control::CycleTimer& timer() const { return timer_; }
  control::CycleTimingReport Report() const { return timer_.Report(); }

 private:
  const PipelineClock& clock_;
  double period_s_;
  ServoNode* node_;
  struct ThreadState {
    int policy = 0, priority = 0;
    std::vector<int> cpus;  // the thread's CPU set before
  };
  ThreadState saved_;  // before ApplyRealtime (initialised first)
  control::RealtimeStatus status_;
  control::CpuLatencyRequest cpu_latency_;  // PM QoS while the loop runs
  control::CycleTimer timer_;
  double t_s_ = 0.0;
};

// The servo's timing as JSON, the same object in `servo --json`, `demo --json` and the RUN
// directory's timing.json (docs/report.md): {"realtime": {"requested", "fifo", "priority",
// "pinned", "cpu", "memory_locked", "refusals": [...], "summary"}, "timing":
// CycleTimingReport::Json(), "deadline": {"hold_after_overruns", "retract_after_ms",
// "resume_after_on_time", "holds", "retracts"}}. No trailing newline.
std::string ServoTimingJson(const control::RealtimeStatus& realtime,
                            const control::CycleTimingReport& timing,
                            const control::DeadlineWatchdogConfig& watchdog,
                            std::uint64_t deadline_holds, std::uint64_t deadline_retracts);

}  // namespace echoservo::live
