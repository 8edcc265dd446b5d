// Ctrl-C (SIGINT) and SIGTERM while an executor (tune/executor.h, tune/slurm_executor.h)
// waits for its trials: for its lifetime an InterruptGuard replaces the process's handlers
// with one that records the signal, so the executor can stop its trials (kill the local
// processes, scancel the job array), keep what finished and return; the previous handlers
// come back when it goes. One guard at a time (the executors run one after another).
#pragma once

#include <csignal>

namespace echoservo::tune {

class InterruptGuard {
 public:
  InterruptGuard();  // clears the record, installs the handler
  ~InterruptGuard();
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

  // The last signal received since construction (0: none), and how many arrived.
  static int signal();
  static int count();

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

}  // namespace echoservo::tune
