// Real-time execution of the servo thread on Linux: a SCHED_FIFO priority, an optional CPU
// to pin it to, and memory locked and pre-faulted so that the 1 kHz cycle never waits for a
// page fault (the recipe of the Linux Foundation's real-time wiki and of ros2_control's
// realtime_tools). Only the calling thread is raised; threads it creates afterwards inherit
// its policy, so callers create their other threads (scanner, tracker, DDS) first.
//
// Refusals by the system (no privilege, RLIMIT_RTPRIO/RLIMIT_MEMLOCK, a CPU outside the
// process's affinity mask) are not errors: each is reported in RealtimeStatus::refusals and
// the thread runs as an ordinary one, as before. Options a user can get wrong (a priority
// outside SCHED_FIFO's range, a CPU that does not exist) throw std::invalid_argument naming
// the command-line option. Builds with AddressSanitizer never lock memory (the sanitizer's
// shadow mappings are terabytes of address space); that is reported as a refusal too, as is
// a finite RLIMIT_MEMLOCK without CAP_IPC_LOCK (locking every future page against such a
// limit would make later allocations fail, so mlockall is not attempted).
// Details: docs/control.md "Real-time execution".
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace echoservo::control {

struct RealtimeOptions {
  bool enabled = true;     // false: run as an ordinary thread, nothing is asked of the system
  int fifo_priority = 80;  // SCHED_FIFO priority, within sched_get_priority_min/max (1–99)
  int cpu = -1;            // pin the thread to this CPU (0-based); -1: no pinning
  // mlockall: current pages and future ones as they are touched; then the stack and heap
  // reserves below are touched once, so they are resident (and locked). false: neither.
  bool lock_memory = true;
  // Stack touched below the caller's frame (≤ 64 MiB; limited to what the thread's stack
  // has left, which is reported as a refusal).
  std::size_t prefault_stack_bytes = 256 * 1024;
  // Heap touched in the calling thread's malloc arena and freed back to it (≤ 1 GiB); the
  // process's M_TRIM_THRESHOLD is raised so the arena keeps those pages.
  std::size_t prefault_heap_bytes = 8 * 1024 * 1024;
  // PM QoS while the servo runs: the CPUs' idle states limited to this exit latency, µs
  // (CpuLatencyRequest below; 0: the shallowest, as cyclictest asks); -1: not requested.
  int cpu_latency_us = 0;

  // Throws std::invalid_argument naming the option (--rt-priority, --servo-cpu,
  // prefault_*_bytes, --cpu-latency-us) when the priority is outside SCHED_FIFO's range,
  // the CPU does not exist on this machine (-1 is "no pinning"), a pre-fault size is past
  // its limit, or the CPU latency is neither -1 nor in [0, 10^6] µs.
  // Checked whether or not `enabled`: a typo is a typo either way.
  void Validate() const;
};

struct RealtimeStatus {
  bool requested = false;  // options.enabled
  bool fifo = false;       // the thread runs under SCHED_FIFO
  int priority = 0;        // its priority (0 when not FIFO)
  bool pinned = false;     // pinned to `cpu`
  int cpu = -1;
  bool memory_locked = false;  // mlockall succeeded
  int cpu_latency_us = -1;     // the PM QoS limit in force (CpuLatencyRequest); -1: none
  // One line per refusal, naming the call, the system's reason and what would allow it,
  // e.g. "SCHED_FIFO priority 80 refused: Operation not permitted (needs root,
  // CAP_SYS_NICE or RLIMIT_RTPRIO ≥ 80); the servo runs at normal priority".
  std::vector<std::string> refusals;

  // "SCHED_FIFO 80, CPU 1, memory locked" / "off (--no-realtime)" / "normal priority,
  // memory not locked (refused: …; …)": scheduling, the CPU when pinned, memory, then the
  // refusals joined by "; ". One line for logs and the JSON summaries.
  std::string Summary() const;
};

// Applies `options` to the calling thread (mlockall to the whole process). Validates first
// (throws as Validate). Never throws for a refusal by the system. The CPU latency request
// is not made here: it lasts only as long as its CpuLatencyRequest object.
RealtimeStatus ApplyRealtime(const RealtimeOptions& options);

// A PM QoS request for the whole machine: while this object lives, no CPU enters an idle
// state whose exit latency exceeds `max_us` (the value written to /dev/cpu_dma_latency, a
// file kept open; closing it withdraws the request — the kernel's interface, and what
// cyclictest does while it measures). Waking a CPU from a deep idle state (or, in a VM, a
// halted vCPU) costs the servo's wake-up hundreds of µs. Refused when the file is missing
// or not writable (needs root): the refusal says so and nothing else changes.
class CpuLatencyRequest {
 public:
  explicit CpuLatencyRequest(int max_us);  // -1: nothing requested
  ~CpuLatencyRequest();
  CpuLatencyRequest(const CpuLatencyRequest&) = delete;
  CpuLatencyRequest& operator=(const CpuLatencyRequest&) = delete;

  bool active() const { return fd_ >= 0; }
  int max_us() const { return active() ? max_us_ : -1; }
  const std::string& refusal() const { return refusal_; }  // empty when active or unasked
  // Records the request in `status` (cpu_latency_us, and the refusal if any).
  void Report(RealtimeStatus& status) const;

 private:
  int fd_ = -1;
  int max_us_ = -1;
  std::string refusal_;
};

// Number of CPUs the machine has (sysconf(_SC_NPROCESSORS_CONF)); at least 1.
int MachineCpuCount();

}  // namespace echoservo::control
