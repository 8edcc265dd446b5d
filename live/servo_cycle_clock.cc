#include "live/servo_cycle_clock.h"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <cerrno>
#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "live/servo_node.h"

namespace echoservo::live {
namespace {

// The calling thread's policy, priority and CPU set.
template <class State>
State SaveThread() {
  State s;
  sched_param p{};
  if (pthread_getschedparam(pthread_self(), &s.policy, &p) == 0) s.priority = p.sched_priority;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (pthread_getaffinity_np(pthread_self(), sizeof(set), &set) == 0) {
    for (int c = 0; c < CPU_SETSIZE; ++c)
      if (CPU_ISSET(c, &set)) s.cpus.push_back(c);
  }
  return s;
}

}  // namespace

ServoCycleClock::ServoCycleClock(const PipelineClock& clock, double period_s, ServoNode* node,
                                 const control::RealtimeOptions& realtime)
    : clock_(clock),
      period_s_(period_s),
      node_(node),
      saved_(SaveThread<ThreadState>()),
      status_(control::ApplyRealtime(realtime)),
      cpu_latency_(realtime.enabled ? realtime.cpu_latency_us : -1),
      timer_(period_s) {
  cpu_latency_.Report(status_);
}

ServoCycleClock::~ServoCycleClock() {
  // Best effort: a thread that was never raised has nothing to undo.
  if (status_.fifo) {
    sched_param p{};
    p.sched_priority = saved_.priority;
    pthread_setschedparam(pthread_self(), saved_.policy, &p);
  }
  if (status_.pinned && !saved_.cpus.empty()) {
    cpu_set_t set;
    CPU_ZERO(&set);
    for (int c : saved_.cpus) CPU_SET(c, &set);
    pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
  }
}

double ServoCycleClock::Wait(std::uint64_t k) {
  t_s_ = static_cast<double>(k) * period_s_;
  // An absolute sleep on CLOCK_MONOTONIC (steady_clock's clock here), as cyclictest sleeps:
  // std::this_thread::sleep_until computes a relative sleep from a clock reading, which
  // oversleeps when the thread is preempted between the two.
  const auto deadline_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(clock_.At(t_s_).time_since_epoch())
          .count();
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline_ns / 1000000000);
  ts.tv_nsec = static_cast<long>(deadline_ns % 1000000000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
  const double woke_s = clock_.Now();
  timer_.Woke(t_s_, woke_s);
  if (node_) node_->NoteWake(woke_s, woke_s - t_s_);
  return t_s_;
}

void ServoCycleClock::Done() {
  const double end_s = clock_.Now();
  const bool overran = timer_.Finished(end_s);
  if (node_) node_->NoteCycleEnd(end_s, overran);
}

std::string ServoTimingJson(const control::RealtimeStatus& realtime,
                            const control::CycleTimingReport& timing,
                            const control::DeadlineWatchdogConfig& watchdog,
                            std::uint64_t deadline_holds, std::uint64_t deadline_retracts) {
  const nlohmann::json j = {
      {"realtime",
       {{"requested", realtime.requested},
        {"fifo", realtime.fifo},
        {"priority", realtime.priority},
        {"pinned", realtime.pinned},
        {"cpu", realtime.pinned ? nlohmann::json(realtime.cpu) : nlohmann::json(nullptr)},
        {"memory_locked", realtime.memory_locked},
        {"refusals", realtime.refusals},
        {"summary", realtime.Summary()}}},
      {"timing", nlohmann::json::parse(timing.Json())},
      {"deadline",
       {{"hold_after_overruns", watchdog.hold_after_overruns},
        {"retract_after_ms", 1000.0 * watchdog.retract_after_s},
        {"resume_after_on_time", watchdog.resume_after_on_time},
        {"holds", deadline_holds},
        {"retracts", deadline_retracts}}}};
  return j.dump();
}

}  // namespace echoservo::live
