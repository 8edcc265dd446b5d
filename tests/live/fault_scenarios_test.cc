// The servo's fault-injection scenarios (live/fault_scenarios.h), in simulated time:
// in every one the servo stays within its travel, velocity and force limits on every
// cycle (0 violations), and reaches its safe state where the fault calls for one, within
// the time its configuration gives: a stale estimate holds after stale_after_s (0.25 s)
// from the last good one, a non-finite sensor stops in the cycle it is read, a STOP in the
// cycle it arrives. Every corrupt estimate or command is rejected. Each scenario's counts
// are printed.
#include "live/fault_scenarios.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <string>

namespace echoservo::live {
namespace {

class FaultInjection : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    for (const FaultScenarioResult& r : RunFaultScenarios(1)) {
      std::printf(
          "fault scenario %-22s injected %5llu  detected %5llu  limit violations %llu  safe after "
          "%.3f s  final %s\n",
          r.name.c_str(), static_cast<unsigned long long>(r.injected),
          static_cast<unsigned long long>(r.detected),
          static_cast<unsigned long long>(r.limit_violations), r.safe_state_after_s,
          r.final_mode.c_str());
      results_[r.name] = r;
    }
  }
  static const FaultScenarioResult& Get(const std::string& name) {
    const auto it = results_.find(name);
    if (it == results_.end()) throw std::logic_error("no scenario " + name);
    return it->second;
  }
  static inline std::map<std::string, FaultScenarioResult> results_;
};

constexpr double kCycleS = 1e-3;
constexpr double kVolumeS = 0.04;

TEST_F(FaultInjection, NoScenarioEverCommandsOutsideALimit) {
  ASSERT_GE(results_.size(), 9u);
  for (const auto& [name, r] : results_) {
    EXPECT_EQ(r.limit_violations, 0u) << name;
    EXPECT_GT(r.injected, 0u) << name;
    EXPECT_EQ(r.cycles, 8001u) << name;
    if (r.safe_state_required) {
      EXPECT_TRUE(r.safe_state_reached) << name;
    }
  }
}

TEST_F(FaultInjection, ALostTrackerHoldsWithinTheStaleTimeThenRetracts) {
  const auto& r = Get("tracker_killed");
  // The last estimate is received ≤ one volume before the fault starts; hold 0.25 s later.
  EXPECT_LE(r.safe_state_after_s, 0.25 + kCycleS);
  EXPECT_EQ(r.final_mode, "retracting");
}

TEST_F(FaultInjection, CorruptEstimatesAreAllRejectedAndTheServoHoldsUntilGoodOnesReturn) {
  const auto& r = Get("estimates_corrupt");
  EXPECT_GE(r.detected, r.injected);  // every corrupt one rejected (plus the stale event)
  EXPECT_LE(r.safe_state_after_s, 0.25 + kVolumeS + kCycleS);
  EXPECT_EQ(r.final_mode, "tracking");  // good estimates resume following (auto-enable)
}

TEST_F(FaultInjection, LossAndDelayKeepFollowingWithinTheServoError) {
  const auto& r = Get("loss_and_delay");
  EXPECT_EQ(r.final_mode, "tracking");
  EXPECT_LT(r.tracking_rms_mm, 0.5);  // the servo's own error is ~0.1–0.2 mm
}

TEST_F(FaultInjection, NonFiniteSensorsStopTheServoInTheCycleTheyAreRead) {
  for (const char* name : {"tip_sensor_nan", "base_sensor_inf", "force_sensor_nan"}) {
    const auto& r = Get(name);
    EXPECT_EQ(r.detected, r.injected) << name;  // every corrupted reading seen
    EXPECT_LE(r.safe_state_after_s, kCycleS) << name;
    EXPECT_EQ(r.final_mode, "stopped") << name;
  }
}

TEST_F(FaultInjection, FrozenOrSpikingTipReadingsStayWithinLimitsAndFollowingGoesOn) {
  for (const char* name : {"tip_sensor_dropout", "tip_sensor_spike"}) {
    const auto& r = Get(name);
    EXPECT_EQ(r.final_mode, "tracking") << name;
    EXPECT_LT(r.tracking_rms_mm, 0.5) << name;
  }
}

TEST_F(FaultInjection, BadCommandsAreRejectedAndAStopIsHonouredInItsCycle) {
  const auto& r = Get("commands_bad_then_stop");
  EXPECT_EQ(r.detected, 3u);
  EXPECT_NEAR(r.safe_state_after_s, 1.0, kCycleS);  // the STOP at 5 s, 1 s after the bad ones
  EXPECT_EQ(r.final_mode, "stopped");
}

}  // namespace
}  // namespace echoservo::live
