#include "control/deadline_watchdog.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace echoservo::control {
namespace {

// "5 ms at 1 kHz", "62.5 ms at 80 Hz": the hold's time span in the user's units.
std::string WatchdogHoldSpan(int overruns, double period_s) {
  const double rate_hz = 1.0 / period_s;
  char buf[96];
  if (rate_hz >= 1000.0) {
    std::snprintf(buf, sizeof buf, "%d overruns = %g ms at %g kHz", overruns,
                  overruns * period_s * 1e3, rate_hz / 1e3);
  } else {
    std::snprintf(buf, sizeof buf, "%d overruns = %g ms at %g Hz", overruns,
                  overruns * period_s * 1e3, rate_hz);
  }
  return buf;
}

std::string WatchdogNumber(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

void WatchdogCheckPeriod(double period_s) {
  if (!(std::isfinite(period_s) && period_s > 0))
    throw std::invalid_argument(
        "DeadlineWatchdog: the servo period must be finite and > 0 s, got " +
        WatchdogNumber(period_s));
}

}  // namespace

void DeadlineWatchdogConfig::Validate(double period_s) const {
  WatchdogCheckPeriod(period_s);
  if (hold_after_overruns < 1)
    throw std::invalid_argument("--deadline-hold-after " + std::to_string(hold_after_overruns) +
                                ": must be at least 1 cycle");
  const double hold_s = hold_after_overruns * period_s;
  if (!(std::isfinite(retract_after_s) && retract_after_s > hold_s))
    throw std::invalid_argument("--deadline-retract-after-ms " +
                                WatchdogNumber(retract_after_s * 1e3) +
                                ": the retraction must come after the hold (" +
                                WatchdogHoldSpan(hold_after_overruns, period_s) + ")");
  if (resume_after_on_time < 1)
    throw std::invalid_argument("--deadline-resume-after " + std::to_string(resume_after_on_time) +
                                ": must be at least 1 on-time cycle");
}

std::string ToString(DeadlineAction action) {
  switch (action) {
    case DeadlineAction::kNone:
      return "none";
    case DeadlineAction::kHold:
      return "hold";
    case DeadlineAction::kRetract:
      return "retract";
  }
  return "unknown";
}

DeadlineWatchdog::DeadlineWatchdog(DeadlineWatchdogConfig config, double period_s)
    : config_(config), period_s_(period_s) {
  config_.Validate(period_s_);
}

// The first call (Woke or CycleEnded) starts the clock of outages: the time before the loop's
// first cycle is not an outage (the catheter was not under this loop's control), and the first
// wake-up's lateness is not judged either: a loop that starts late (thread creation, memory
// locking and pre-faulting before the first deadline) has not left the catheter unattended.
DeadlineAction DeadlineWatchdog::Woke(double now_s, double lateness_s) {
  if (!started_) {
    started_ = true;
    last_on_time_s_ = now_s;
    return action_;
  }
  if (action_ != DeadlineAction::kRetract && lateness_s >= config_.retract_after_s) {
    action_ = DeadlineAction::kRetract;
    ++retracts_;
  }
  return action_;
}

DeadlineAction DeadlineWatchdog::CycleEnded(double now_s, bool overran) {
  if (!started_) {
    started_ = true;
    last_on_time_s_ = now_s;
  }
  if (overran) {
    ++consecutive_;
    on_time_streak_ = 0;
    if (action_ == DeadlineAction::kNone &&
        consecutive_ >= static_cast<std::uint64_t>(config_.hold_after_overruns)) {
      action_ = DeadlineAction::kHold;
      ++holds_;
    }
    // An open streak of overruns (consecutive_ > 0 here) that has lasted retract_after_s since
    // the last on-time cycle is an outage.
    if (action_ != DeadlineAction::kRetract && now_s - last_on_time_s_ >= config_.retract_after_s) {
      action_ = DeadlineAction::kRetract;
      ++retracts_;
    }
  } else {
    consecutive_ = 0;
    last_on_time_s_ = now_s;
    ++on_time_streak_;
    if (action_ == DeadlineAction::kHold &&
        on_time_streak_ >= static_cast<std::uint64_t>(config_.resume_after_on_time))
      action_ = DeadlineAction::kNone;
  }
  return action_;
}

void DeadlineWatchdog::Reset(double now_s) {
  action_ = DeadlineAction::kNone;
  started_ = true;
  last_on_time_s_ = now_s;
  consecutive_ = 0;
  on_time_streak_ = 0;
}

}  // namespace echoservo::control
