// The one servo runtime: it owns the 1 kHz loop around a ServoNode (live/servo_node.h) for
// every command — `servo`, `demo`, `tune trial`, `faults` — as ros2_control's controller
// manager owns read → update → write and a Drake Simulator owns a System's loop.
//
// Two choices, nothing else differs between commands:
// - Clock policy. kRealtime: the servo cycle clock (live/servo_cycle_clock.h) raises the
//   calling thread (SCHED_FIFO, CPU, locked memory), sleeps to each absolute deadline
//   t = t0 + k·period on the pipeline clock, times every cycle and feeds the node's deadline
//   watchdog. kSimulated: t = t0 + k·period with no waiting (replays, fault scenarios): the
//   same cycles, as fast as the host runs them.
// - Estimate feed. The node's own DDS subscription (a node built with a participant), or an
//   in-process DelayedEstimates queue, handed to the node when each estimate is due.
// Per cycle, in order: `before(k, t)` (scenario hooks, commands), the due estimates, the node's
// Cycle, `after(k, t, cycle)` (the caller's bookkeeping); the loop ends after duration_s (0:
// never) or when `stop` says so. Units: s. Errors: std::invalid_argument for bad options.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>

#include "control/cycle_timing.h"
#include "control/realtime.h"
#include "link/samples.h"
#include "live/pipeline_clock.h"

namespace echoservo::live {

class ServoNode;
struct ServoCycle;

enum class ServoClock { kRealtime, kSimulated };

// Estimates delivered in process, each at its own time (a replay's imaging delay, a fault
// scenario's extra delay): Push in any order of delivery time; Deliver hands the node, in
// delivery order, every estimate due by `t_s`. Single-threaded (the servo's thread).
class DelayedEstimates {
 public:
  void Push(const link::TargetEstimateSample& sample, double deliver_s);
  // Hands every estimate due by t_s to node.HandleTarget; returns how many.
  std::size_t Deliver(ServoNode& node, double t_s);
  std::size_t pending() const { return queue_.size(); }

 private:
  struct Due {
    link::TargetEstimateSample sample;
    double deliver_s = 0.0;
  };
  std::deque<Due> queue_;
};

struct ServoRuntimeOptions {
  ServoClock clock = ServoClock::kRealtime;
  // kRealtime: the pipeline clock the deadlines are on (must outlive the run), and the real-
  // time settings the calling thread gets (refusals are reported, not errors).
  const PipelineClock* pipeline_clock = nullptr;
  control::RealtimeOptions realtime;
  double t0_s = 0.0;                      // the first cycle's time
  double duration_s = 0.0;                // cycles while t ≤ t0_s + duration_s; 0: until stop
  DelayedEstimates* estimates = nullptr;  // in-process feed; null: the node's DDS link
  std::function<bool()> stop;             // checked every cycle; may be null
  void Validate() const;                  // throws std::invalid_argument naming the field
};

struct ServoRunResult {
  std::uint64_t cycles = 0;
  double end_s = 0.0;  // the last cycle's time
  // kRealtime only: what the system granted the thread, and the cycle timing.
  control::RealtimeStatus realtime;
  control::CycleTimingReport timing;
};

class ServoRuntime {
 public:
  using Before = std::function<void(std::uint64_t k, double t_s)>;
  using After = std::function<void(std::uint64_t k, double t_s, const ServoCycle& cycle)>;

  // `node` must outlive the runtime. Throws std::invalid_argument for bad options.
  ServoRuntime(ServoNode& node, ServoRuntimeOptions options);

  // Starts the node at t0_s and runs the loop on the calling thread (raised to real time for
  // kRealtime: call it after the other threads exist). `before` and `after` may be null.
  // With kRealtime, `on_started(status)` (may be null) is told what the system granted
  // before the first cycle.
  ServoRunResult Run(const Before& before, const After& after,
                     const std::function<void(const control::RealtimeStatus&)>& on_started = {});

 private:
  ServoNode& node_;
  ServoRuntimeOptions o_;
};

}  // namespace echoservo::live
