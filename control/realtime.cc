// Real-time scheduling, CPU pinning and memory locking of the servo thread
// (control/realtime.h). Every system call's failure becomes one refusal line; only the
// user's options are errors.
#include "control/realtime.h"

#include <alloca.h>
#include <fcntl.h>
#include <linux/capability.h>
#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ECHOSERVO_REALTIME_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) && !defined(ECHOSERVO_REALTIME_ASAN)
#define ECHOSERVO_REALTIME_ASAN 1
#endif

#ifndef MCL_ONFAULT
#define MCL_ONFAULT 4  // Linux ≥ 4.4; older C libraries lack the name
#endif

namespace echoservo::control {
namespace {

constexpr std::size_t kRealtimeMaxStackBytes = std::size_t{64} * 1024 * 1024;
constexpr std::size_t kRealtimeMaxHeapBytes = std::size_t{1024} * 1024 * 1024;
// Left untouched below the pre-faulted stack: the guard page and what the callees of
// ApplyRealtime itself need.
constexpr std::size_t kRealtimeStackMarginBytes = 64 * 1024;
// Heap reserve blocks stay below glibc's default mmap threshold (128 KiB), so they come
// from the arena and return to it (not to the system) when freed.
constexpr std::size_t kRealtimeHeapBlockBytes = 64 * 1024;

std::string RealtimeErrnoText(int error) {
  char buffer[256];
  // GNU strerror_r returns the text (maybe not in buffer).
  return strerror_r(error, buffer, sizeof buffer);
}

std::string RealtimeRlimitText(int resource) {
  rlimit limit{};
  if (getrlimit(resource, &limit) != 0) return "unknown";
  if (limit.rlim_cur == RLIM_INFINITY) return "unlimited";
  return std::to_string(static_cast<unsigned long long>(limit.rlim_cur));
}

// Whether the process may lock memory past RLIMIT_MEMLOCK (CAP_IPC_LOCK is effective).
[[maybe_unused]] bool RealtimeHasIpcLock() {
  __user_cap_header_struct header{};
  header.version = _LINUX_CAPABILITY_VERSION_3;
  header.pid = 0;
  __user_cap_data_struct data[_LINUX_CAPABILITY_U32S_3] = {};
  if (syscall(SYS_capget, &header, data) != 0) return false;
  return (data[CAP_TO_INDEX(CAP_IPC_LOCK)].effective & CAP_TO_MASK(CAP_IPC_LOCK)) != 0;
}

std::string RealtimeKiB(std::size_t bytes) { return std::to_string(bytes / 1024) + " KiB"; }

std::size_t RealtimePageBytes() {
  const long page = sysconf(_SC_PAGESIZE);
  return page > 0 ? static_cast<std::size_t>(page) : 4096;
}

// Writes one byte per page of `bytes` of fresh stack below the caller's frame, from the
// top down so that a main thread's stack grows page by page. Not inlined, so the alloca'd
// block is this function's own and is released when it returns.
[[gnu::noinline]] void RealtimeTouchStack(std::size_t bytes, std::size_t page) {
  volatile char* block = static_cast<volatile char*>(alloca(bytes));
  for (std::size_t offset = 0; offset < bytes; offset += page) block[bytes - 1 - offset] = 0;
  block[0] = 0;
}

// Bytes of stack the calling thread has left below this frame (0 when unknown).
std::size_t RealtimeStackBytesLeft() {
  pthread_attr_t attr;
  if (pthread_getattr_np(pthread_self(), &attr) != 0) return 0;
  void* low = nullptr;
  std::size_t size = 0;
  const int rc = pthread_attr_getstack(&attr, &low, &size);
  pthread_attr_destroy(&attr);
  if (rc != 0 || low == nullptr) return 0;
  volatile char here = 0;
  const auto here_address = reinterpret_cast<std::uintptr_t>(&here);
  const auto low_address = reinterpret_cast<std::uintptr_t>(low);
  if (here_address <= low_address || here_address - low_address > size) return 0;
  return here_address - low_address;
}

void RealtimePrefaultStack(std::size_t requested, RealtimeStatus& status) {
  if (requested == 0) return;
  const std::size_t left = RealtimeStackBytesLeft();
  std::size_t bytes = requested;
  if (left <= kRealtimeStackMarginBytes) {
    bytes = 0;
  } else if (bytes > left - kRealtimeStackMarginBytes) {
    bytes = left - kRealtimeStackMarginBytes;
  }
  if (bytes < requested) {
    status.refusals.push_back("stack pre-fault limited to " + RealtimeKiB(bytes) + " of the " +
                              RealtimeKiB(requested) + " asked: the thread has " +
                              RealtimeKiB(left) + " of stack left (give it a larger stack)");
  }
  if (bytes > 0) RealtimeTouchStack(bytes, RealtimePageBytes());
}

// Touches `bytes` of heap in arena-sized blocks and frees them; with the trim threshold
// raised the arena keeps those pages, so later allocations of the thread reuse resident
// (and, after mlockall, locked) memory.
void RealtimePrefaultHeap(std::size_t bytes) {
  if (bytes == 0) return;
  mallopt(M_TRIM_THRESHOLD, INT_MAX);
  const std::size_t page = RealtimePageBytes();
  std::vector<void*> blocks;
  blocks.reserve(bytes / kRealtimeHeapBlockBytes + 1);
  for (std::size_t done = 0; done < bytes; done += kRealtimeHeapBlockBytes) {
    auto* block = static_cast<volatile char*>(std::malloc(kRealtimeHeapBlockBytes));
    if (block == nullptr) break;
    for (std::size_t i = 0; i < kRealtimeHeapBlockBytes; i += page) block[i] = 0;
    blocks.push_back(const_cast<char*>(block));
  }
  for (void* block : blocks) std::free(block);
}

void RealtimeLockMemory(const RealtimeOptions& options, RealtimeStatus& status) {
#if defined(ECHOSERVO_REALTIME_ASAN)
  status.refusals.push_back(
      "mlockall not called: this build uses AddressSanitizer, whose shadow memory spans "
      "terabytes of address space; memory is not locked (a Release build locks it)");
#else
  rlimit limit{};
  const bool unlimited = getrlimit(RLIMIT_MEMLOCK, &limit) == 0 && limit.rlim_cur == RLIM_INFINITY;
  if (!unlimited && !RealtimeHasIpcLock()) {
    // MCL_FUTURE counts every later mapping against the limit: once it is reached, mmap
    // and malloc fail. Without the privilege to exceed it, do not lock.
    status.refusals.push_back(
        "mlockall not called: RLIMIT_MEMLOCK is " + RealtimeRlimitText(RLIMIT_MEMLOCK) +
        " bytes and the process lacks CAP_IPC_LOCK, so locking all future memory would make "
        "later allocations fail (needs root, CAP_IPC_LOCK or RLIMIT_MEMLOCK unlimited); memory "
        "is not locked and the servo may wait on page faults");
  } else {
    int rc = mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT);
    if (rc != 0 && errno == EINVAL) rc = mlockall(MCL_CURRENT | MCL_FUTURE);  // no ONFAULT
    if (rc == 0) {
      status.memory_locked = true;
    } else {
      const int error = errno;
      status.refusals.push_back("mlockall refused: " + RealtimeErrnoText(error) +
                                " (needs root, CAP_IPC_LOCK or RLIMIT_MEMLOCK unlimited, now " +
                                RealtimeRlimitText(RLIMIT_MEMLOCK) +
                                " bytes); memory is not locked and the servo may wait on "
                                "page faults");
    }
  }
#endif
  RealtimePrefaultStack(options.prefault_stack_bytes, status);
  RealtimePrefaultHeap(options.prefault_heap_bytes);
}

std::string RealtimeCpuListText(const cpu_set_t* set, std::size_t set_bytes, int cpus) {
  std::string text;
  for (int cpu = 0; cpu < cpus; ++cpu) {
    if (!CPU_ISSET_S(cpu, set_bytes, set)) continue;
    int last = cpu;
    while (last + 1 < cpus && CPU_ISSET_S(last + 1, set_bytes, set)) ++last;
    if (!text.empty()) text += ",";
    text += std::to_string(cpu);
    if (last > cpu) text += "–" + std::to_string(last);
    cpu = last;
  }
  return text.empty() ? "none" : text;
}

void RealtimePin(int cpu, RealtimeStatus& status) {
  const int cpus = std::max(MachineCpuCount(), CPU_SETSIZE);
  const std::size_t set_bytes = CPU_ALLOC_SIZE(cpus);
  cpu_set_t* allowed = CPU_ALLOC(cpus);
  cpu_set_t* wanted = CPU_ALLOC(cpus);
  if (allowed == nullptr || wanted == nullptr) {
    status.refusals.push_back("CPU " + std::to_string(cpu) +
                              " not pinned: no memory for a CPU set; the servo thread runs "
                              "on any CPU");
  } else {
    CPU_ZERO_S(set_bytes, allowed);
    CPU_ZERO_S(set_bytes, wanted);
    CPU_SET_S(static_cast<std::size_t>(cpu), set_bytes, wanted);
    if (pthread_getaffinity_np(pthread_self(), set_bytes, allowed) != 0) {
      CPU_ZERO_S(set_bytes, allowed);  // unknown: let pthread_setaffinity_np decide
      CPU_SET_S(static_cast<std::size_t>(cpu), set_bytes, allowed);
    }
    if (!CPU_ISSET_S(static_cast<std::size_t>(cpu), set_bytes, allowed)) {
      status.refusals.push_back(
          "CPU " + std::to_string(cpu) + " is outside the CPUs this process may use (" +
          RealtimeCpuListText(allowed, set_bytes, MachineCpuCount()) +
          ", set by taskset, a cgroup's cpuset or the container); the servo thread is not "
          "pinned");
    } else if (const int error = pthread_setaffinity_np(pthread_self(), set_bytes, wanted);
               error != 0) {
      status.refusals.push_back("pthread_setaffinity_np to CPU " + std::to_string(cpu) +
                                " refused: " + RealtimeErrnoText(error) +
                                "; the servo thread is not pinned");
    } else {
      status.pinned = true;
      status.cpu = cpu;
    }
  }
  if (allowed != nullptr) CPU_FREE(allowed);
  if (wanted != nullptr) CPU_FREE(wanted);
}

void RealtimeRaiseToFifo(int priority, RealtimeStatus& status) {
  sched_param param{};
  param.sched_priority = priority;
  const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  if (error != 0) {
    status.refusals.push_back(
        "SCHED_FIFO priority " + std::to_string(priority) +
        " refused: " + RealtimeErrnoText(error) + " (needs root, CAP_SYS_NICE or RLIMIT_RTPRIO ≥ " +
        std::to_string(priority) + ", now " + RealtimeRlimitText(RLIMIT_RTPRIO) +
        "; in a container also a real-time CPU budget); the servo runs at normal priority");
  }
  int policy = SCHED_OTHER;
  sched_param now{};
  if (pthread_getschedparam(pthread_self(), &policy, &now) == 0 && policy == SCHED_FIFO) {
    status.fifo = true;
    status.priority = now.sched_priority;
  }
}

}  // namespace

void RealtimeOptions::Validate() const {
  const int low = sched_get_priority_min(SCHED_FIFO);
  const int high = sched_get_priority_max(SCHED_FIFO);
  if (fifo_priority < low || fifo_priority > high) {
    throw std::invalid_argument("--rt-priority " + std::to_string(fifo_priority) +
                                ": SCHED_FIFO priorities on this system are " +
                                std::to_string(low) + "–" + std::to_string(high));
  }
  const int cpus = MachineCpuCount();
  if (cpu < -1 || cpu >= cpus) {
    throw std::invalid_argument(
        "--servo-cpu " + std::to_string(cpu) + ": this machine has " + std::to_string(cpus) +
        (cpus == 1 ? " CPU (0)" : " CPUs (0–" + std::to_string(cpus - 1) + ")") +
        "; -1 leaves the thread unpinned");
  }
  if (prefault_stack_bytes > kRealtimeMaxStackBytes) {
    throw std::invalid_argument("RealtimeOptions::prefault_stack_bytes " +
                                std::to_string(prefault_stack_bytes) +
                                ": at most 64 MiB (a servo thread's stack is far smaller)");
  }
  if (cpu_latency_us < -1 || cpu_latency_us > 1000000) {
    throw std::invalid_argument("--cpu-latency-us " + std::to_string(cpu_latency_us) +
                                ": a CPU wake-up latency in [0, 1000000] µs, or -1 for none");
  }
  if (prefault_heap_bytes > kRealtimeMaxHeapBytes) {
    throw std::invalid_argument("RealtimeOptions::prefault_heap_bytes " +
                                std::to_string(prefault_heap_bytes) + ": at most 1 GiB");
  }
}

std::string RealtimeStatus::Summary() const {
  if (!requested) return "off (--no-realtime)";
  std::string text = fifo ? "SCHED_FIFO " + std::to_string(priority) : "normal priority";
  if (pinned) text += ", CPU " + std::to_string(cpu);
  text += memory_locked ? ", memory locked" : ", memory not locked";
  if (cpu_latency_us >= 0) text += ", CPU wake-up ≤ " + std::to_string(cpu_latency_us) + " µs";
  if (!refusals.empty()) {
    text += " (refused: ";
    for (std::size_t i = 0; i < refusals.size(); ++i) {
      if (i > 0) text += "; ";
      text += refusals[i];
    }
    text += ")";
  }
  return text;
}

RealtimeStatus ApplyRealtime(const RealtimeOptions& options) {
  options.Validate();
  RealtimeStatus status;
  status.requested = options.enabled;
  if (!options.enabled) return status;
  if (options.lock_memory) RealtimeLockMemory(options, status);
  if (options.cpu >= 0) RealtimePin(options.cpu, status);
  RealtimeRaiseToFifo(options.fifo_priority, status);
  return status;
}

CpuLatencyRequest::CpuLatencyRequest(int max_us) : max_us_(max_us) {
  if (max_us < 0) return;
  const char* path = "/dev/cpu_dma_latency";
  const int fd = open(path, O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    refusal_ = std::string("CPU wake-up latency ≤ ") + std::to_string(max_us) +
               " µs (PM QoS) refused: cannot open " + path + ": " + std::strerror(errno) +
               " (needs root or write access to it); deep CPU idle states stay allowed";
    return;
  }
  const std::int32_t value = max_us;
  if (write(fd, &value, sizeof value) != static_cast<ssize_t>(sizeof value)) {
    refusal_ = std::string("CPU wake-up latency ≤ ") + std::to_string(max_us) +
               " µs (PM QoS) refused: writing " + path + ": " + std::strerror(errno);
    close(fd);
    return;
  }
  fd_ = fd;
}

CpuLatencyRequest::~CpuLatencyRequest() {
  if (fd_ >= 0) close(fd_);  // withdraws the request
}

void CpuLatencyRequest::Report(RealtimeStatus& status) const {
  status.cpu_latency_us = max_us();
  if (!refusal_.empty()) status.refusals.push_back(refusal_);
}

int MachineCpuCount() {
  const long cpus = sysconf(_SC_NPROCESSORS_CONF);
  return cpus >= 1 && cpus <= INT_MAX ? static_cast<int>(cpus) : 1;
}

}  // namespace echoservo::control
