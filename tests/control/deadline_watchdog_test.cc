// The deadline watchdog (control/deadline_watchdog.h): its state machine on synthetic cycle
// times (hold exactly at the K-th consecutive overrun, retraction after an outage made of a
// run of overruns or of one late wake-up, the end of a hold, the retraction latched until
// Reset, the counters), the options' validation messages, and one run on the real clock with
// a cycle made slow on purpose, timed by control/cycle_timing.h's CycleTimer.
//
// The synthetic times are multiples of a period of 2⁻¹⁰ s and the retraction time 2⁻⁴ s
// (64 periods), so every comparison of times is exact and the cycle at which an action
// starts is known from the header's rules alone.
#include "control/deadline_watchdog.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>

#include "control/cycle_timing.h"

namespace echoservo::control {
namespace {

constexpr double kSyntheticPeriodS = 1.0 / 1024;  // exact in binary
constexpr double kSyntheticRetractS = 64 * kSyntheticPeriodS;

DeadlineWatchdogConfig WatchdogConfigFor(int k = 5, int resume = 3) {
  DeadlineWatchdogConfig c;
  c.hold_after_overruns = k;
  c.retract_after_s = kSyntheticRetractS;
  c.resume_after_on_time = resume;
  return c;
}

// Cycle n ends at n periods (exact).
double CycleEnd(int n) { return n * kSyntheticPeriodS; }

TEST(DeadlineWatchdog, HoldsExactlyAtTheKthConsecutiveOverrunAndNotBefore) {
  for (int k : {1, 2, 5}) {
    DeadlineWatchdog w(WatchdogConfigFor(k), kSyntheticPeriodS);
    int n = 0;
    for (int i = 0; i < 10; ++i)
      EXPECT_EQ(w.CycleEnded(CycleEnd(n++), false), DeadlineAction::kNone);
    // K − 1 overruns, broken by an on-time cycle, three times over: never a hold.
    for (int round = 0; round < 3; ++round) {
      for (int i = 0; i < k - 1; ++i)
        EXPECT_EQ(w.CycleEnded(CycleEnd(n++), true), DeadlineAction::kNone) << "K " << k;
      EXPECT_EQ(w.consecutive_overruns(), static_cast<std::uint64_t>(k - 1));
      EXPECT_EQ(w.CycleEnded(CycleEnd(n++), false), DeadlineAction::kNone);
      EXPECT_EQ(w.consecutive_overruns(), 0u);
    }
    EXPECT_EQ(w.holds(), 0u);
    for (int i = 0; i < k - 1; ++i)
      EXPECT_EQ(w.CycleEnded(CycleEnd(n++), true), DeadlineAction::kNone);
    EXPECT_EQ(w.CycleEnded(CycleEnd(n++), true), DeadlineAction::kHold) << "K " << k;
    EXPECT_EQ(w.action(), DeadlineAction::kHold);
    EXPECT_EQ(w.holds(), 1u);
    // Further overruns keep the hold without counting new ones.
    EXPECT_EQ(w.CycleEnded(CycleEnd(n++), true), DeadlineAction::kHold);
    EXPECT_EQ(w.holds(), 1u);
    EXPECT_EQ(w.retracts(), 0u);
  }
}

TEST(DeadlineWatchdog, ARunOfOverrunsRetractsWhenNoCycleWasOnTimeForTheRetractionTime) {
  DeadlineWatchdog w(WatchdogConfigFor(5), kSyntheticPeriodS);
  for (int n = 0; n <= 100; ++n) w.CycleEnded(CycleEnd(n), false);  // last on time: cycle 100
  // Overruns from cycle 101: hold at 105, retraction at the first end ≥ 100 + 64 periods.
  for (int n = 101; n < 164; ++n) {
    const DeadlineAction a = w.CycleEnded(CycleEnd(n), true);
    EXPECT_EQ(a, n < 105 ? DeadlineAction::kNone : DeadlineAction::kHold) << n;
  }
  EXPECT_EQ(w.CycleEnded(CycleEnd(164), true), DeadlineAction::kRetract);
  EXPECT_EQ(w.holds(), 1u);
  EXPECT_EQ(w.retracts(), 1u);
}

TEST(DeadlineWatchdog, SlowCyclesThatOverrunFewerThanKInARowNeverRetractOrHold) {
  // Every second cycle overruns for a long time: the loop still finishes a cycle on time
  // every two periods, which is neither K overruns in a row nor an outage.
  DeadlineWatchdog w(WatchdogConfigFor(2), kSyntheticPeriodS);
  for (int n = 0; n < 1000; ++n)
    EXPECT_EQ(w.CycleEnded(CycleEnd(n), n % 2 == 1), DeadlineAction::kNone);
  EXPECT_EQ(w.holds(), 0u);
  EXPECT_EQ(w.retracts(), 0u);
}

TEST(DeadlineWatchdog, OneWakeUpAsLateAsTheRetractionTimeRetractsByItself) {
  DeadlineWatchdog w(WatchdogConfigFor(5), kSyntheticPeriodS);
  // The first wake-up's lateness is not judged (the loop starting late is no outage).
  EXPECT_EQ(w.Woke(0.0, 10 * kSyntheticRetractS), DeadlineAction::kNone);
  EXPECT_EQ(w.CycleEnded(CycleEnd(1), false), DeadlineAction::kNone);
  EXPECT_EQ(w.Woke(CycleEnd(2), kSyntheticRetractS - kSyntheticPeriodS), DeadlineAction::kNone);
  EXPECT_EQ(w.CycleEnded(CycleEnd(2), false), DeadlineAction::kNone);
  EXPECT_EQ(w.Woke(CycleEnd(3) + kSyntheticRetractS, kSyntheticRetractS), DeadlineAction::kRetract);
  EXPECT_EQ(w.holds(), 0u);  // no hold on the way: one cycle was late, not K
  EXPECT_EQ(w.retracts(), 1u);
  // Latched: a late wake-up again counts no second retraction.
  EXPECT_EQ(w.Woke(CycleEnd(200), 2 * kSyntheticRetractS), DeadlineAction::kRetract);
  EXPECT_EQ(w.retracts(), 1u);
}

TEST(DeadlineWatchdog, AHoldEndsAfterResumeOnTimeCyclesInARow) {
  DeadlineWatchdog w(WatchdogConfigFor(3, 4), kSyntheticPeriodS);
  int n = 0;
  w.CycleEnded(CycleEnd(n++), false);
  for (int i = 0; i < 3; ++i) w.CycleEnded(CycleEnd(n++), true);
  ASSERT_EQ(w.action(), DeadlineAction::kHold);
  // Three on-time cycles, an overrun (the streak starts again), then four.
  for (int i = 0; i < 3; ++i) EXPECT_EQ(w.CycleEnded(CycleEnd(n++), false), DeadlineAction::kHold);
  EXPECT_EQ(w.CycleEnded(CycleEnd(n++), true), DeadlineAction::kHold);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(w.CycleEnded(CycleEnd(n++), false), DeadlineAction::kHold);
  EXPECT_EQ(w.CycleEnded(CycleEnd(n++), false), DeadlineAction::kNone);
  // K overruns again: a second hold.
  for (int i = 0; i < 2; ++i) EXPECT_EQ(w.CycleEnded(CycleEnd(n++), true), DeadlineAction::kNone);
  EXPECT_EQ(w.CycleEnded(CycleEnd(n++), true), DeadlineAction::kHold);
  EXPECT_EQ(w.holds(), 2u);
  EXPECT_EQ(w.retracts(), 0u);
}

TEST(DeadlineWatchdog, ARetractionIsLatchedUntilResetWhichKeepsTheCounters) {
  DeadlineWatchdog w(WatchdogConfigFor(5, 1), kSyntheticPeriodS);
  w.CycleEnded(CycleEnd(0), false);
  ASSERT_EQ(w.Woke(CycleEnd(1) + kSyntheticRetractS, kSyntheticRetractS), DeadlineAction::kRetract);
  for (int n = 100; n < 400; ++n)
    EXPECT_EQ(w.CycleEnded(CycleEnd(n), false), DeadlineAction::kRetract);
  for (int n = 400; n < 500; ++n)
    EXPECT_EQ(w.CycleEnded(CycleEnd(n), true), DeadlineAction::kRetract);
  EXPECT_EQ(w.holds(), 0u);  // latched retraction: no hold counted under it
  w.Reset(CycleEnd(500));
  EXPECT_EQ(w.action(), DeadlineAction::kNone);
  EXPECT_EQ(w.consecutive_overruns(), 0u);
  EXPECT_EQ(w.retracts(), 1u);
  // The outage clock restarts at Reset: overruns from there hold at the 5th and retract
  // 64 periods after the Reset, not after the last on-time cycle (399).
  for (int n = 501; n < 564; ++n)
    EXPECT_NE(w.CycleEnded(CycleEnd(n), true), DeadlineAction::kRetract) << n;
  EXPECT_EQ(w.action(), DeadlineAction::kHold);
  EXPECT_EQ(w.CycleEnded(CycleEnd(564), true), DeadlineAction::kRetract);
  EXPECT_EQ(w.holds(), 1u);
  EXPECT_EQ(w.retracts(), 2u);
}

TEST(DeadlineWatchdog, TheFirstCycleStartsTheOutageClock) {
  // A loop whose first cycle overruns at t = 10 s has no outage before it: the retraction
  // comes 64 periods after that first cycle's end.
  DeadlineWatchdog w(WatchdogConfigFor(5), kSyntheticPeriodS);
  const double t0 = 10.0;
  for (int n = 0; n < 64; ++n)
    EXPECT_NE(w.CycleEnded(t0 + CycleEnd(n), true), DeadlineAction::kRetract);
  EXPECT_EQ(w.CycleEnded(t0 + CycleEnd(64), true), DeadlineAction::kRetract);
}

std::string WatchdogValidateMessage(const DeadlineWatchdogConfig& c, double period_s) {
  try {
    c.Validate(period_s);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(DeadlineWatchdog, BadOptionsAreRejectedNamingTheOption) {
  EXPECT_NO_THROW(DeadlineWatchdogConfig{}.Validate(1e-3));  // the defaults: K = 10, 50 ms, 50
  // K = 5, 50 ms, 200 below.
  const auto five = [] {
    DeadlineWatchdogConfig f;
    f.hold_after_overruns = 5;
    f.resume_after_on_time = 200;
    return f;
  };
  DeadlineWatchdogConfig c = five();
  EXPECT_NO_THROW(c.Validate(1e-3));
  c.hold_after_overruns = 0;
  EXPECT_EQ(WatchdogValidateMessage(c, 1e-3), "--deadline-hold-after 0: must be at least 1 cycle");
  c.hold_after_overruns = -3;
  EXPECT_NE(WatchdogValidateMessage(c, 1e-3).find("--deadline-hold-after -3"), std::string::npos);
  c = five();
  c.retract_after_s = 0.003;
  EXPECT_EQ(WatchdogValidateMessage(c, 1e-3),
            "--deadline-retract-after-ms 3: the retraction must come after the hold (5 "
            "overruns = 5 ms at 1 kHz)");
  c.retract_after_s = 0.005;  // at the hold itself: still not after it
  EXPECT_NE(WatchdogValidateMessage(c, 1e-3).find("--deadline-retract-after-ms 5:"),
            std::string::npos);
  EXPECT_NO_THROW(c.Validate(0.5e-3));  // at 2 kHz the hold comes at 2.5 ms
  EXPECT_NE(WatchdogValidateMessage(c, 0.01).find("(5 overruns = 50 ms at 100 Hz)"),
            std::string::npos);
  for (double bad :
       {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(), -1.0}) {
    c.retract_after_s = bad;
    EXPECT_NE(WatchdogValidateMessage(c, 1e-3).find("--deadline-retract-after-ms"),
              std::string::npos)
        << bad;
  }
  c = five();
  c.resume_after_on_time = 0;
  EXPECT_EQ(WatchdogValidateMessage(c, 1e-3),
            "--deadline-resume-after 0: must be at least 1 on-time cycle");
  // The constructor validates, and rejects a period that is not a time.
  EXPECT_THROW(DeadlineWatchdog(c, 1e-3), std::invalid_argument);
  for (double period : {0.0, -1e-3, std::numeric_limits<double>::quiet_NaN()})
    EXPECT_THROW(DeadlineWatchdog(DeadlineWatchdogConfig{}, period), std::invalid_argument)
        << period;
}

TEST(DeadlineWatchdog, ActionsHaveNames) {
  EXPECT_EQ(ToString(DeadlineAction::kNone), "none");
  EXPECT_EQ(ToString(DeadlineAction::kHold), "hold");
  EXPECT_EQ(ToString(DeadlineAction::kRetract), "retract");
}

// On the real clock: a 1 kHz loop whose every cycle is made slow on purpose (busy for 2.5
// periods) overruns every cycle whatever the scheduler does (CycleTimer must say so). With
// every cycle overrunning, the header's rules say: hold at the K-th cycle's end; retract at
// the first cycle end at least retract_after_s after the first wake-up (the first call starts
// the outage clock), or earlier at a wake-up (after the first) at least retract_after_s late
// — which only a preemption of the test thread for ~15 ms could cause on a loaded machine.
// Those rules are applied here to the measured times and the watchdog must agree exactly.
TEST(DeadlineWatchdog, ALoopMadeSlowOnPurposeHoldsAtTheKthCycleThenRetracts) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point origin = Clock::now();
  auto now_s = [&] { return std::chrono::duration<double>(Clock::now() - origin).count(); };
  constexpr double kP = 1e-3, kWorkS = 2.5e-3;
  DeadlineWatchdogConfig c;
  c.hold_after_overruns = 4;
  c.retract_after_s = 0.02;
  DeadlineWatchdog w(c, kP);
  CycleTimer timer(kP);
  // What the watchdog said, and what the rules say, as (cycle, 0 at wake-up / 1 at its end).
  int hold_at = -1, retract_at = -1, expected_hold_at = -1, expected_retract_at = -1;
  double first_woke_s = 0.0;
  int k = 0;
  for (; k < 60 && retract_at < 0; ++k) {
    const double deadline_s = 1e-3 + k * kP;
    while (now_s() < deadline_s) std::this_thread::yield();
    const double woke_s = now_s();
    if (k == 0) first_woke_s = woke_s;
    timer.Woke(deadline_s, woke_s);
    if (w.Woke(woke_s, woke_s - deadline_s) == DeadlineAction::kRetract) retract_at = 2 * k;
    if (expected_retract_at < 0 && k > 0 && woke_s - deadline_s >= c.retract_after_s)
      expected_retract_at = 2 * k;
    while (now_s() < woke_s + kWorkS) {
    }
    const double end_s = now_s();
    const bool overran = timer.Finished(end_s);
    ASSERT_TRUE(overran) << "cycle " << k << " busy for 2.5 periods did not overrun";
    const DeadlineAction a = w.CycleEnded(end_s, overran);
    if (a == DeadlineAction::kHold && hold_at < 0) hold_at = 2 * k + 1;
    if (a == DeadlineAction::kRetract && retract_at < 0) retract_at = 2 * k + 1;
    if (expected_retract_at < 0 && expected_hold_at < 0 && k + 1 == c.hold_after_overruns)
      expected_hold_at = 2 * k + 1;
    if (expected_retract_at < 0 && end_s - first_woke_s >= c.retract_after_s)
      expected_retract_at = 2 * k + 1;
  }
  EXPECT_EQ(hold_at, expected_hold_at);
  EXPECT_EQ(retract_at, expected_retract_at);
  ASSERT_GE(retract_at, 0);
  // Without a long preemption: the hold at the 4th cycle, the retraction by the end of the
  // cycle whose end first lies 20 ms after the first wake-up, at 2.5 ms a cycle the 8th.
  if (expected_hold_at >= 0) {
    EXPECT_EQ(expected_hold_at, 2 * (c.hold_after_overruns - 1) + 1);
  }
  EXPECT_LE(k, static_cast<int>(c.retract_after_s / kWorkS) + 1);
  EXPECT_EQ(timer.consecutive_overruns(), static_cast<std::uint64_t>(k));
  EXPECT_EQ(w.holds(), expected_hold_at >= 0 ? 1u : 0u);
  EXPECT_EQ(w.retracts(), 1u);
}

}  // namespace
}  // namespace echoservo::control
