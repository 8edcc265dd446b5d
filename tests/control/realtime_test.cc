// Real-time options and their application (control/realtime.h). What the kernel did is read
// back from the kernel (pthread_getschedparam, sched_getcpu, VmLck in /proc/self/status),
// not from the status ApplyRealtime returns. The thread raised is one the test creates, so
// the test runner never runs SCHED_FIFO, and memory is unlocked again afterwards. Refusals
// are provoked for real in a forked child that drops CAP_SYS_NICE and CAP_IPC_LOCK and
// lowers RLIMIT_RTPRIO and RLIMIT_MEMLOCK to 0 (the state of an unprivileged user), and
// narrows its CPU set.
#include "control/realtime.h"

#include <gtest/gtest.h>
#include <linux/capability.h>
#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "tests/test_util/expect_error.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo::control {
namespace {

using testing::ExpectContains;
using testing::InvalidArgumentMessage;

// VmLck of this process in bytes (0 when unreadable).
std::size_t RealtimeTestLockedBytes() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmLck:") {
      std::size_t kib = 0;
      status >> kib;
      return kib * 1024;
    }
    status.ignore(4096, '\n');
  }
  return 0;
}

bool RealtimeTestRefused(const RealtimeStatus& status, const std::string& what) {
  for (const std::string& line : status.refusals)
    if (line.find(what) != std::string::npos) return true;
  return false;
}

TEST(RealtimeOptionsTest, ValidateNamesTheOption) {
  const int low = sched_get_priority_min(SCHED_FIFO);
  const int high = sched_get_priority_max(SCHED_FIFO);
  const std::string range = std::to_string(low) + "–" + std::to_string(high);
  for (int priority : {low - 1, high + 1, 120}) {
    RealtimeOptions o;
    o.fifo_priority = priority;
    const std::string message = InvalidArgumentMessage([&] { o.Validate(); });
    ExpectContains(message, "--rt-priority " + std::to_string(priority));
    ExpectContains(message, "SCHED_FIFO priorities on this system are " + range);
  }
  const int cpus = MachineCpuCount();
  for (int cpu : {cpus, 64 + cpus, -2}) {
    RealtimeOptions o;
    o.cpu = cpu;
    const std::string message = InvalidArgumentMessage([&] { o.Validate(); });
    ExpectContains(message, "--servo-cpu " + std::to_string(cpu));
    ExpectContains(message, "this machine has " + std::to_string(cpus) + " CPU");
  }
  RealtimeOptions big_stack;
  big_stack.prefault_stack_bytes = std::size_t{65} * 1024 * 1024;
  ExpectContains(InvalidArgumentMessage([&] { big_stack.Validate(); }), "prefault_stack_bytes");
  RealtimeOptions big_heap;
  big_heap.prefault_heap_bytes = std::size_t{2} * 1024 * 1024 * 1024;
  ExpectContains(InvalidArgumentMessage([&] { big_heap.Validate(); }), "prefault_heap_bytes");
  for (int us : {-2, 1000001}) {
    RealtimeOptions latency;
    latency.cpu_latency_us = us;
    ExpectContains(InvalidArgumentMessage([&] { latency.Validate(); }),
                   "--cpu-latency-us " + std::to_string(us));
  }

  // A typo is reported even when real-time is off, and ApplyRealtime validates first.
  RealtimeOptions off;
  off.enabled = false;
  off.fifo_priority = high + 1;
  ExpectContains(InvalidArgumentMessage([&] { ApplyRealtime(off); }), "--rt-priority");

  RealtimeOptions edges;
  edges.fifo_priority = high;
  edges.cpu = cpus - 1;
  EXPECT_NO_THROW(edges.Validate());
  edges.fifo_priority = low;
  edges.cpu = -1;
  EXPECT_NO_THROW(edges.Validate());
}

TEST(RealtimeTest, DisabledAsksNothing) {
  RealtimeOptions o;
  o.enabled = false;
  o.cpu = 0;
  RealtimeStatus status;
  int policy = -1;
  std::thread([&] {
    status = ApplyRealtime(o);
    sched_param param{};
    pthread_getschedparam(pthread_self(), &policy, &param);
  }).join();
  EXPECT_FALSE(status.requested);
  EXPECT_FALSE(status.fifo);
  EXPECT_FALSE(status.pinned);
  EXPECT_FALSE(status.memory_locked);
  EXPECT_TRUE(status.refusals.empty());
  EXPECT_EQ(policy, SCHED_OTHER);
  EXPECT_EQ(status.Summary(), "off (--no-realtime)");
}

TEST(RealtimeTest, RaisesPinsAndLocksTheCallingThread) {
  RealtimeOptions o;
  o.fifo_priority = sched_get_priority_min(SCHED_FIFO) + 1;
  o.cpu = MachineCpuCount() - 1;
  o.prefault_stack_bytes = 128 * 1024;
  o.prefault_heap_bytes = 1024 * 1024;
  RealtimeStatus status;
  int policy = -1, priority = -1, cpu_after_yield = -1;
  std::size_t locked_bytes = 0;
  std::thread([&] {
    status = ApplyRealtime(o);
    sched_param param{};
    pthread_getschedparam(pthread_self(), &policy, &param);
    priority = param.sched_priority;
    sched_yield();
    cpu_after_yield = sched_getcpu();
    locked_bytes = RealtimeTestLockedBytes();
  }).join();
  if (status.memory_locked) munlockall();  // leave the rest of the test process unlocked

  EXPECT_TRUE(status.requested);
  if (RealtimeTestRefused(status, "SCHED_FIFO")) {
    GTEST_SKIP() << "this system refuses SCHED_FIFO: " << status.Summary();
  }
  EXPECT_TRUE(status.fifo);
  EXPECT_EQ(policy, SCHED_FIFO);
  EXPECT_EQ(priority, o.fifo_priority);
  EXPECT_EQ(status.priority, o.fifo_priority);
  ExpectContains(status.Summary(), "SCHED_FIFO " + std::to_string(o.fifo_priority));
  if (RealtimeTestRefused(status, "outside the CPUs this process may use")) {
    EXPECT_FALSE(status.pinned);
  } else {
    EXPECT_TRUE(status.pinned) << status.Summary();
    EXPECT_EQ(status.cpu, o.cpu);
    EXPECT_EQ(cpu_after_yield, o.cpu);
    ExpectContains(status.Summary(), "CPU " + std::to_string(o.cpu));
  }
  if (testing::kUnderSanitizers) {
    EXPECT_FALSE(status.memory_locked);
    EXPECT_TRUE(RealtimeTestRefused(status, "AddressSanitizer")) << status.Summary();
  } else if (status.memory_locked) {
    // VmLck counts the pages locked: at least those touched after mlockall (the process's
    // resident pages are locked too, so this proves the lock, not the pre-fault; that is
    // PrefaultMakesTheStackAndHeapReserveResident).
    EXPECT_GE(locked_bytes, o.prefault_stack_bytes + o.prefault_heap_bytes);
    ExpectContains(status.Summary(), "memory locked");
  } else {
    EXPECT_TRUE(RealtimeTestRefused(status, "mlock")) << status.Summary();
  }
}

struct RealtimeTestPrefaultRun {
  RealtimeOptions options;
  RealtimeStatus status;
  long heap_free_after = 0;  // mallinfo2().fordblks: free bytes in all arenas
};

void* RealtimeTestPrefaultThread(void* arg) {
  auto* run = static_cast<RealtimeTestPrefaultRun*>(arg);
  run->status = ApplyRealtime(run->options);
  run->heap_free_after = static_cast<long>(mallinfo2().fordblks);
  return nullptr;
}

// Runs ApplyRealtime in a thread whose stack is a fresh mapping (no page resident until
// touched) and returns how many bytes of that stack are resident afterwards (mincore).
std::size_t RealtimeTestResidentStack(RealtimeTestPrefaultRun& run) {
  const std::size_t stack_bytes = 1024 * 1024;
  const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  void* stack = mmap(nullptr, stack_bytes, PROT_READ | PROT_WRITE,
                     MAP_PRIVATE | MAP_ANONYMOUS | MAP_STACK, -1, 0);
  if (stack == MAP_FAILED) {
    ADD_FAILURE() << "mmap of a test stack failed";
    return 0;
  }
  pthread_attr_t attr;
  pthread_attr_init(&attr);
  pthread_attr_setstack(&attr, stack, stack_bytes);
  pthread_t thread;
  if (pthread_create(&thread, &attr, RealtimeTestPrefaultThread, &run) == 0) {
    pthread_join(thread, nullptr);
  } else {
    ADD_FAILURE() << "pthread_create failed";
  }
  pthread_attr_destroy(&attr);
  if (run.status.memory_locked) munlockall();
  std::vector<unsigned char> resident(stack_bytes / page);
  std::size_t resident_bytes = 0;
  if (mincore(stack, stack_bytes, resident.data()) == 0) {
    for (unsigned char r : resident) resident_bytes += (r & 1) ? page : 0;
  }
  munmap(stack, stack_bytes);
  return resident_bytes;
}

TEST(RealtimeTest, PrefaultMakesTheStackAndHeapReserveResident) {
  RealtimeTestPrefaultRun without;  // lock_memory = false: nothing touched
  without.options.lock_memory = false;
  without.options.fifo_priority = sched_get_priority_min(SCHED_FIFO);
  const std::size_t resident_without = RealtimeTestResidentStack(without);

  RealtimeTestPrefaultRun with;
  with.options.fifo_priority = sched_get_priority_min(SCHED_FIFO);
  with.options.prefault_stack_bytes = 512 * 1024;
  with.options.prefault_heap_bytes = 4 * 1024 * 1024;
  const std::size_t resident_with = RealtimeTestResidentStack(with);

  // Without pre-fault the thread touches a few pages (its descriptor, TLS and frames).
  EXPECT_LT(resident_without, std::size_t{128} * 1024);
  EXPECT_GE(resident_with, with.options.prefault_stack_bytes) << with.status.Summary();
  EXPECT_FALSE(RealtimeTestRefused(with.status, "stack pre-fault")) << with.status.Summary();
  if (!testing::kUnderSanitizers) {  // ASan has its own allocator; mallinfo2 says nothing
    // The reserve was freed back to the thread's arena and kept there (not trimmed): the
    // arenas hold at least that much free memory. (Not a difference from before: a thread
    // may reuse an arena that earlier tests left with free memory.) Half the reserve: other
    // threads of the test runner may allocate from the same arena meanwhile.
    EXPECT_GE(with.heap_free_after, static_cast<long>(with.options.prefault_heap_bytes / 2));
  }
}

// Fills *status with ApplyRealtime's result in a thread whose stack is `stack_bytes`.
void* RealtimeTestSmallStackThread(void* arg) {
  auto* status = static_cast<RealtimeStatus*>(arg);
  RealtimeOptions o;
  o.prefault_stack_bytes = 1024 * 1024;
  o.prefault_heap_bytes = 0;
  o.fifo_priority = sched_get_priority_min(SCHED_FIFO);
  *status = ApplyRealtime(o);
  return nullptr;
}

TEST(RealtimeTest, StackPrefaultIsLimitedToTheThreadsStack) {
  pthread_attr_t attr;
  ASSERT_EQ(pthread_attr_init(&attr), 0);
  ASSERT_EQ(pthread_attr_setstacksize(&attr, 256 * 1024), 0);
  RealtimeStatus status;
  pthread_t thread;
  ASSERT_EQ(pthread_create(&thread, &attr, RealtimeTestSmallStackThread, &status), 0);
  pthread_join(thread, nullptr);
  pthread_attr_destroy(&attr);
  if (status.memory_locked) munlockall();
  // 1 MiB asked of a 256 KiB stack: no crash, and the shortfall is reported.
  EXPECT_TRUE(RealtimeTestRefused(status, "stack pre-fault limited")) << status.Summary();
  EXPECT_TRUE(RealtimeTestRefused(status, "1024 KiB asked")) << status.Summary();
}

// In a forked child: drops the privileges that allow real-time scheduling and memory
// locking, narrows the CPU set to the first CPU it may use, applies `options` asking for
// another CPU (none on a 1-CPU machine); returns what the child saw as
// "policy\nkept CPU\nasked CPU\nSummary". The child is single-threaded (the parent's other
// threads are not forked).
std::string RealtimeTestUnprivilegedChild(const RealtimeOptions& options) {
  int fds[2];
  if (pipe(fds) != 0) return "pipe failed";
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    __user_cap_header_struct header{};
    header.version = _LINUX_CAPABILITY_VERSION_3;
    __user_cap_data_struct data[_LINUX_CAPABILITY_U32S_3] = {};
    syscall(SYS_capget, &header, data);
    for (int cap : {CAP_SYS_NICE, CAP_IPC_LOCK}) {
      data[CAP_TO_INDEX(cap)].effective &= ~CAP_TO_MASK(cap);
      data[CAP_TO_INDEX(cap)].permitted &= ~CAP_TO_MASK(cap);
    }
    syscall(SYS_capset, &header, data);
    const rlimit zero{0, 0};
    setrlimit(RLIMIT_RTPRIO, &zero);
    setrlimit(RLIMIT_MEMLOCK, &zero);
    // Keep only the first CPU the child may use and ask for another one that exists.
    RealtimeOptions asked = options;
    cpu_set_t allowed;
    CPU_ZERO(&allowed);
    sched_getaffinity(0, sizeof allowed, &allowed);
    int keep = 0;
    while (keep < CPU_SETSIZE - 1 && !CPU_ISSET(keep, &allowed)) ++keep;
    cpu_set_t only_keep;
    CPU_ZERO(&only_keep);
    CPU_SET(keep, &only_keep);
    sched_setaffinity(0, sizeof only_keep, &only_keep);
    asked.cpu = MachineCpuCount() > 1 ? (keep == 0 ? 1 : 0) : -1;
    std::string text;
    try {
      const RealtimeStatus status = ApplyRealtime(asked);
      int policy = -1;
      sched_param param{};
      pthread_getschedparam(pthread_self(), &policy, &param);
      text = std::to_string(policy) + "\n" + std::to_string(keep) + "\n" +
             std::to_string(asked.cpu) + "\n" + status.Summary();
    } catch (const std::exception& e) {
      text = std::string("threw: ") + e.what();
    }
    const ssize_t written = write(fds[1], text.data(), text.size());
    _exit(written == static_cast<ssize_t>(text.size()) ? 0 : 1);
  }
  close(fds[1]);
  std::string text;
  char buffer[4096];
  for (ssize_t n; (n = read(fds[0], buffer, sizeof buffer)) > 0;) text.append(buffer, n);
  close(fds[0]);
  int wstatus = 0;
  waitpid(pid, &wstatus, 0);
  EXPECT_TRUE(WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 0) << text;
  return text;
}

TEST(RealtimeTest, RefusalsWithoutPrivilegeAreReportedAndTheThreadRunsAsBefore) {
  RealtimeOptions o;
  o.fifo_priority = 50 <= sched_get_priority_max(SCHED_FIFO) ? 50 : 1;
  const std::string text = RealtimeTestUnprivilegedChild(o);
  std::vector<std::string> fields;
  std::size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const std::size_t newline = text.find('\n', start);
    ASSERT_NE(newline, std::string::npos) << text;
    fields.push_back(text.substr(start, newline - start));
    start = newline + 1;
  }
  const std::string summary = text.substr(start);
  EXPECT_EQ(fields[0], std::to_string(SCHED_OTHER)) << text;  // still an ordinary thread
  EXPECT_EQ(summary.rfind("normal priority, memory not locked (refused: ", 0), 0u) << summary;
  const std::string p = std::to_string(o.fifo_priority);
  ExpectContains(summary, "SCHED_FIFO priority " + p + " refused: Operation not permitted");
  ExpectContains(summary, "CAP_SYS_NICE or RLIMIT_RTPRIO ≥ " + p + ", now 0");
  ExpectContains(summary, "the servo runs at normal priority");
  if (!testing::kUnderSanitizers) ExpectContains(summary, "CAP_IPC_LOCK");  // else: ASan
  ExpectContains(summary, "memory is not locked");
  if (fields[2] != "-1") {
    ExpectContains(summary, "CPU " + fields[2] + " is outside the CPUs this process may use (" +
                                fields[1] + ",");
    ExpectContains(summary, "the servo thread is not pinned");
  }
}

// The machine's PM QoS CPU latency in force (the binary int32 /dev/cpu_dma_latency reads
// as); nullopt when it cannot be read.
std::optional<std::int32_t> CpuLatencyInForce() {
  std::ifstream in("/dev/cpu_dma_latency", std::ios::binary);
  std::int32_t v = 0;
  if (!in.read(reinterpret_cast<char*>(&v), sizeof v)) return std::nullopt;
  return v;
}

TEST(CpuLatencyRequestTest, HoldsTheLimitWhileItLivesOrSaysWhyNot) {
  const std::optional<std::int32_t> before = CpuLatencyInForce();
  {
    const CpuLatencyRequest none(-1);
    EXPECT_FALSE(none.active());
    EXPECT_TRUE(none.refusal().empty());
  }
  {
    const CpuLatencyRequest r(7);
    RealtimeStatus status;
    status.requested = true;
    r.Report(status);
    if (!r.active()) {  // no root, or no such file: said, never silent
      EXPECT_FALSE(r.refusal().empty());
      ASSERT_EQ(status.refusals.size(), 1u);
      EXPECT_EQ(status.cpu_latency_us, -1);
      GTEST_SKIP() << r.refusal();
    }
    EXPECT_EQ(status.cpu_latency_us, 7);
    EXPECT_TRUE(status.refusals.empty());
    EXPECT_NE(status.Summary().find("CPU wake-up ≤ 7 µs"), std::string::npos) << status.Summary();
    // The kernel takes the smallest request in force: at most ours.
    const std::optional<std::int32_t> during = CpuLatencyInForce();
    ASSERT_TRUE(during.has_value());
    EXPECT_LE(*during, 7);
  }
  // Withdrawn with the object: back to what it was (unless another process asked meanwhile).
  if (before) {
    EXPECT_EQ(CpuLatencyInForce(), before);
  }
}

}  // namespace
}  // namespace echoservo::control
