// The servo's reaction to missed deadlines. A 1 kHz loop that keeps overrunning is no longer
// controlling the catheter at the rate its gains were tuned for, and one that stops running
// for tens of milliseconds leaves the catheter unattended inside a beating heart. After K
// consecutive overruns the watchdog asks for a hold (the servo keeps the tip where it is);
// when the loop has not finished a cycle on time for `retract_after_s` — a run of overruns,
// or one wake-up that late — it asks for a retraction, which stays latched until Reset (the
// operator's ENABLE). A hold ends after `resume_after_on_time` consecutive on-time cycles.
// Times in s on the loop's monotonic clock. Details: docs/control.md "Missed deadlines".
#pragma once

#include <cstdint>
#include <string>

namespace echoservo::control {

struct DeadlineWatchdogConfig {
  int hold_after_overruns = 10;   // K ≥ 1 consecutive overruns → hold
  double retract_after_s = 0.05;  // no on-time cycle for this long → retract
  int resume_after_on_time = 50;  // on-time cycles that end a hold (≥ 1)
  // Throws std::invalid_argument naming the option (--deadline-hold-after,
  // --deadline-retract-after-ms, --deadline-resume-after) when K < 1, when the retraction
  // would come before the hold (retract_after_s ≤ K · period_s), or resume < 1.
  void Validate(double period_s) const;
};

enum class DeadlineAction : std::uint8_t { kNone, kHold, kRetract };
std::string ToString(DeadlineAction action);  // "none", "hold", "retract"

class DeadlineWatchdog {
 public:
  // Throws std::invalid_argument as DeadlineWatchdogConfig::Validate, or for a period ≤ 0.
  DeadlineWatchdog(DeadlineWatchdogConfig config, double period_s);
  // At wake-up: the cycle started `lateness_s` after its deadline. A lateness of at least
  // retract_after_s is an outage by itself. Returns the action in force.
  DeadlineAction Woke(double now_s, double lateness_s);
  // At the end of each cycle's work: whether it overran (control/cycle_timing.h).
  DeadlineAction CycleEnded(double now_s, bool overran);
  // Back to kNone (the operator enabled the servo again); counters are kept.
  void Reset(double now_s);

  DeadlineAction action() const { return action_; }
  std::uint64_t holds() const { return holds_; }        // transitions into kHold
  std::uint64_t retracts() const { return retracts_; }  // transitions into kRetract
  std::uint64_t consecutive_overruns() const { return consecutive_; }
  const DeadlineWatchdogConfig& config() const { return config_; }

 private:
  DeadlineWatchdogConfig config_;
  double period_s_;
  DeadlineAction action_ = DeadlineAction::kNone;
  double last_on_time_s_ = 0.0;  // end of the last on-time cycle (or Reset / first call)
  bool started_ = false;
  std::uint64_t consecutive_ = 0, on_time_streak_ = 0, holds_ = 0, retracts_ = 0;
};

}  // namespace echoservo::control
