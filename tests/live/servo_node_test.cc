// live::ServoNode without a link (estimates and commands fed directly, on the simulated
// catheter): the mode and fault mapping onto the state topic, the operator's commands, the
// stale-estimate watchdog (hold after stale_after_s, retract after retract_after_s more),
// a stop honoured in the cycle it arrives in, non-finite estimates rejected and counted,
// and every limit respected on every cycle (limit_violations = 0).
#include "live/servo_node.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "hw/hardware_interface.h"
#include "live/sim_catheter.h"

namespace echoservo::live {
namespace {

constexpr double kPeriod = 1e-3;

// A target estimate acquired 1 ms before t: the target at 10 mm + 2 mm·sin(2π·1 Hz·t)
// along a fixed axis, the tip seen where the catheter's tip is (image = catheter
// coordinates), so the catheter follows 10 − standoff.
link::TargetEstimateSample Estimate(double t, std::uint64_t seq, double tip_mm) {
  link::TargetEstimateSample s;
  s.sequence_number = seq;
  s.acquisition_time_s = t - 0.001;
  s.publication_time_s = t - 0.001;
  s.axis = Eigen::Vector3d::UnitZ();
  s.target_mm = Eigen::Vector3d(0, 0, 10);
  s.tip_mm = Eigen::Vector3d(0, 0, tip_mm);
  s.motion.t0_s = 0.0;
  s.motion.frequency_hz = 1.0;
  s.motion.offset_mm = 10.0;
  s.motion.cos_mm = {0.0};
  s.motion.sin_mm = {2.0};
  s.motion.valid_until_s = s.acquisition_time_s + 0.5;
  s.confidence = 0.9;
  return s;
}

link::ServoCommandSample Command(link::ServoAction a, double t, double standoff_mm = 0.0) {
  link::ServoCommandSample c;
  c.sequence_number = static_cast<std::uint64_t>(t * 1e3);
  c.stamp_s = t;
  c.action = a;
  c.standoff_mm = standoff_mm;
  return c;
}

struct Rig {
  SimCatheter catheter = MakeSimCatheter(1.59, 1.50, 1);
  ServoNode node;
  std::uint64_t k = 0;
  explicit Rig(ServoNodeOptions o)
      : node(*catheter.plant, catheter.servo, std::move(catheter.compensator), o, nullptr) {
    node.Start(0.0);
  }
  double t() const { return static_cast<double>(k) * kPeriod; }
  double Tip() const { return catheter.plant->state(hw::iface::kTipPosition); }
  ServoCycle Step() { return node.Cycle(t(), k++); }
  // Runs until `until_s`, feeding an estimate every 40 ms when `feed`.
  ServoCycle RunUntil(double until_s, bool feed, std::uint64_t* seq) {
    ServoCycle c;
    while (t() < until_s) {
      if (feed && k % 40 == 0) node.HandleTarget(Estimate(t(), ++*seq, Tip()), t());
      c = Step();
    }
    return c;
  }
};

TEST(ServoNodeMapping, FollowerModesAndFaultsMapOntoTheStateTopic) {
  EXPECT_EQ(ToLinkMode(control::FollowerMode::kDisabled), link::ServoMode::kIdle);
  EXPECT_EQ(ToLinkMode(control::FollowerMode::kFollowing), link::ServoMode::kTracking);
  EXPECT_EQ(ToLinkMode(control::FollowerMode::kHolding), link::ServoMode::kHolding);
  EXPECT_EQ(ToLinkMode(control::FollowerMode::kRetracting), link::ServoMode::kRetracting);
  EXPECT_EQ(ToLinkMode(control::FollowerMode::kStopped), link::ServoMode::kStopped);
  EXPECT_EQ(ToLinkFaults(control::follower_fault::kStaleEstimate), link::fault::kStaleEstimate);
  EXPECT_EQ(ToLinkFaults(control::follower_fault::kRejectedEstimate),
            link::fault::kInvalidEstimate);
  EXPECT_EQ(ToLinkFaults(control::follower_fault::kTravelLimit), link::fault::kTravelLimit);
  EXPECT_EQ(
      ToLinkFaults(control::follower_fault::kStopRequested | control::follower_fault::kRetracted),
      0u);
}

TEST(ServoNode, FollowsAfterEnableThenHoldsAndRetractsWhenEstimatesStop) {
  ServoNodeOptions o;
  o.follower.standoff_mm = 3.0;
  Rig rig(o);
  std::uint64_t seq = 0;
  ServoCycle c = rig.RunUntil(0.5, true, &seq);
  EXPECT_EQ(c.mode, link::ServoMode::kIdle);  // no ENABLE yet
  ASSERT_TRUE(rig.node.HandleCommand(Command(link::ServoAction::kEnable, rig.t(), 3.0), rig.t()));
  c = rig.RunUntil(3.0, true, &seq);
  EXPECT_EQ(c.mode, link::ServoMode::kTracking);
  // Following: the tip within a millimetre of target − standoff (servo error ~0.2 mm).
  const double setpoint = 10.0 + 2.0 * std::sin(2 * M_PI * rig.t()) - 3.0;
  EXPECT_NEAR(c.record.reference_mm, setpoint, 0.05);
  EXPECT_NEAR(c.record.tip_mm, setpoint, 1.0);
  EXPECT_EQ(rig.node.State(rig.t()).mode, link::ServoMode::kTracking);
  EXPECT_DOUBLE_EQ(rig.node.State(rig.t()).standoff_mm, 3.0);
  // Estimates stop at 3.0 s (the newest received at 2.96 s):
  // hold 0.25 s after the last receipt, retract 0.5 s later.
  const double last_receipt = 2.96;
  c = rig.RunUntil(last_receipt + 0.25 - 0.01, false, &seq);
  EXPECT_EQ(c.mode, link::ServoMode::kTracking);
  c = rig.RunUntil(last_receipt + 0.25 + 0.01, false, &seq);
  EXPECT_EQ(c.mode, link::ServoMode::kHolding);
  EXPECT_TRUE(c.faults & link::fault::kStaleEstimate);
  c = rig.RunUntil(last_receipt + 0.75 + 0.01, false, &seq);
  EXPECT_EQ(c.mode, link::ServoMode::kRetracting);
  EXPECT_TRUE(rig.node.State(rig.t()).faults & link::fault::kStaleEstimate);
  EXPECT_GE(rig.node.stats().fault_events, 1u);
  EXPECT_EQ(rig.node.stats().limit_violations, 0u);
}

TEST(ServoNode, StopIsHonouredInTheCycleItArrivesIn) {
  ServoNodeOptions o;
  o.auto_enable = true;
  Rig rig(o);
  std::uint64_t seq = 0;
  ServoCycle c = rig.RunUntil(2.0, true, &seq);
  ASSERT_EQ(c.mode, link::ServoMode::kTracking);
  ASSERT_TRUE(rig.node.HandleCommand(Command(link::ServoAction::kStop, rig.t()), rig.t()));
  c = rig.Step();
  EXPECT_EQ(c.mode, link::ServoMode::kStopped);
  const double held = c.record.reference_mm;
  // Estimates keep coming; a stopped servo stays stopped and holds its reference.
  c = rig.RunUntil(3.0, true, &seq);
  EXPECT_EQ(c.mode, link::ServoMode::kStopped);
  EXPECT_NEAR(c.record.reference_mm, held, 1e-9);
  EXPECT_EQ(rig.node.stats().limit_violations, 0u);
}

TEST(ServoNode, NonFiniteAndStaleEstimatesAndBadCommandsAreRejectedAndCounted) {
  ServoNodeOptions o;
  o.auto_enable = true;
  Rig rig(o);
  std::uint64_t seq = 0;
  rig.RunUntil(1.0, true, &seq);
  const std::uint64_t accepted = rig.node.stats().estimates_accepted;
  link::TargetEstimateSample bad = Estimate(rig.t(), ++seq, rig.Tip());
  bad.motion.offset_mm = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(rig.node.HandleTarget(bad, rig.t()));
  bad = Estimate(rig.t(), ++seq, rig.Tip());
  bad.acquisition_time_s = rig.t() - 10.0;  // far older than the link's staleness limit
  bad.motion.t0_s = bad.acquisition_time_s;
  bad.motion.valid_until_s = bad.acquisition_time_s + 0.5;
  EXPECT_FALSE(rig.node.HandleTarget(bad, rig.t()));
  EXPECT_EQ(rig.node.stats().estimates_rejected, 2u);
  EXPECT_EQ(rig.node.stats().estimates_accepted, accepted);
  EXPECT_FALSE(
      rig.node.HandleCommand(Command(link::ServoAction::kSetStandoff, rig.t(), 45.0), rig.t()));
  EXPECT_EQ(rig.node.stats().commands_rejected, 1u);
  const ServoCycle c = rig.RunUntil(1.5, true, &seq);
  EXPECT_EQ(c.mode, link::ServoMode::kTracking);  // the good stream goes on
  EXPECT_EQ(rig.node.stats().limit_violations, 0u);
}

TEST(ServoNode, BadOptionsThrowNamingTheField) {
  ServoNodeOptions o;
  o.state_rate_hz = 0;
  try {
    o.Validate();
    FAIL() << "accepted state_rate_hz = 0";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("state_rate_hz"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace echoservo::live
