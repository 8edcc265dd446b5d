// live::ServoNode without a link (estimates and commands fed directly, on the simulated
// catheter): the mode and fault mapping onto the state topic, the operator's commands, the
// stale-estimate watchdog (hold after stale_after_s, retract after retract_after_s more),
// a stop honoured in the cycle it arrives in (and one queued overtaking the commands before
// it), non-finite estimates rejected and counted, every limit respected on every cycle
// (limit_violations = 0), and the deadline watchdog's hold and retraction.
#include "live/servo_node.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

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
  EXPECT_EQ(ToLinkFaults(control::fault::kStaleEstimate), link::fault::kStaleEstimate);
  EXPECT_EQ(ToLinkFaults(control::fault::kInvalidEstimate), link::fault::kInvalidEstimate);
  EXPECT_EQ(ToLinkFaults(control::fault::kTravelLimit), link::fault::kTravelLimit);
  EXPECT_EQ(ToLinkFaults(control::fault::kImageNotResponding), link::fault::kImageNotResponding);
  EXPECT_EQ(ToLinkFaults(control::fault::kStopRequested | control::fault::kRetracted), 0u);
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

// The failure at the node, in simulated time: a static image (a scanner serving a
// still scene: the tip always seen at 0 mm, the target at 10 mm, so following at the 8 mm
// standoff steps the catheter by 2 mm), 25 vol/s acquired 60 ms before they arrive, the
// follower configured as `echoservo servo` configures it. The response check faults within
// 2 s of following; the servo holds at once and retracts after retract_after_s (the
// stale-estimate watchdog's path), never reports tracking again, does not auto-resume,
// publishes the fault bit, and spends no time at a clamp after the fault.
TEST(ServoNode, AStaticImageRaisesImageNotRespondingThenHoldsAndRetractsWithoutClamping) {
  ServoNodeOptions o;
  o.follower.standoff_mm = 8.0;
  o.follower.offset_gain = 0.05;
  o.follower.estimate_scale = true;
  o.auto_enable = true;
  Rig rig(o);
  std::uint64_t seq = 0;
  double tracking_s = -1, fault_s = -1, hold_s = -1, retract_s = -1, clamped_after_s = 0;
  bool tracking_after_fault = false, bit_published = false;
  while (rig.t() < 6.0) {
    if (rig.k % 40 == 0 && rig.t() >= 0.06) {
      link::TargetEstimateSample s = Estimate(rig.t(), ++seq, 0.0);
      s.acquisition_time_s = rig.t() - 0.06;
      s.motion.sin_mm = {0.0};
      s.motion.valid_until_s = s.acquisition_time_s + 0.5;
      ASSERT_TRUE(rig.node.HandleTarget(s, rig.t()));
    }
    const ServoCycle c = rig.Step();
    const double t = rig.t() - kPeriod;
    if (c.mode == link::ServoMode::kTracking && tracking_s < 0) tracking_s = t;
    if ((c.faults & link::fault::kImageNotResponding) && fault_s < 0) fault_s = t;
    if (fault_s >= 0) {
      if (hold_s < 0 && c.mode == link::ServoMode::kHolding) hold_s = t;
      if (retract_s < 0 && c.mode == link::ServoMode::kRetracting) retract_s = t;
      tracking_after_fault |= c.mode == link::ServoMode::kTracking;
      if (c.clamped) clamped_after_s += kPeriod;
      bit_published |= (rig.node.State(t).faults & link::fault::kImageNotResponding) != 0;
    }
  }
  ASSERT_GE(tracking_s, 0);
  ASSERT_GE(fault_s, 0) << "no image-not-responding fault";
  std::printf("static image: fault %.3f s after following began, retracting %.3f s after it\n",
              fault_s - tracking_s, retract_s - fault_s);
  EXPECT_LE(fault_s - tracking_s, 2.0);
  EXPECT_EQ(hold_s, fault_s);
  EXPECT_NEAR(retract_s - fault_s, o.follower.retract_after_s, 2 * kPeriod);
  EXPECT_FALSE(tracking_after_fault);
  EXPECT_TRUE(bit_published);
  EXPECT_EQ(clamped_after_s, 0.0);
  EXPECT_EQ(rig.node.stats().image_not_responding, 1u);
  EXPECT_EQ(rig.node.stats().resumes, 0u);
  EXPECT_EQ(rig.node.stats().limit_violations, 0u);
  // An operator's ENABLE re-arms: following again, until the still image faults again.
  ASSERT_TRUE(rig.node.HandleCommand(Command(link::ServoAction::kEnable, rig.t(), 8.0), rig.t()));
  EXPECT_EQ(rig.Step().mode, link::ServoMode::kTracking);
}

// Honest clamp accounting: with the follower's travel ending at 8 mm, a reference of
// 7 + 2·sin(2π·t) mm (target 10 ± 2 mm, standoff 3 mm, image = catheter) lies beyond it
// while sin(2π·t) > 0.5, a third of every period. The node counts that time (every cycle of
// it an intervention), the travel bit is set exactly then, and the image, which answers,
// raises no fault.
TEST(ServoNode, TimeAtTheTravelClampIsCountedAndEveryClampedCycleIsAnIntervention) {
  ServoNodeOptions o;
  o.follower.standoff_mm = 3.0;
  o.follower.travel_max_mm = 8.0;
  o.auto_enable = true;
  Rig rig(o);
  std::uint64_t seq = 0;
  rig.RunUntil(1.0, true, &seq);  // following from the first estimate
  const double clamped_before = rig.node.stats().time_at_clamp_s;
  const std::uint64_t interventions_before = rig.node.stats().limit_interventions;
  std::uint64_t bit_cycles = 0, clamped_cycles = 0;
  while (rig.t() < 5.0) {
    if (rig.k % 40 == 0) rig.node.HandleTarget(Estimate(rig.t(), ++seq, rig.Tip()), rig.t());
    const ServoCycle c = rig.Step();
    ASSERT_EQ(c.mode, link::ServoMode::kTracking);
    clamped_cycles += c.clamped;
    bit_cycles += (c.faults & link::fault::kTravelLimit) != 0;
  }
  const ServoNodeStats& st = rig.node.stats();
  // 4 periods × 1/3 s; a cycle either side of each of the 4 clamped stretches.
  EXPECT_NEAR(st.time_at_clamp_s - clamped_before, 4.0 / 3.0, 8 * kPeriod);
  EXPECT_NEAR(static_cast<double>(clamped_cycles) * kPeriod, 4.0 / 3.0, 8 * kPeriod);
  EXPECT_GE(st.limit_interventions - interventions_before, clamped_cycles);
  // The published bit: the clamp now or within the compensator's look-ahead (≤ 10 ms each).
  EXPECT_GE(bit_cycles, clamped_cycles);
  EXPECT_LE(bit_cycles, clamped_cycles + 4 * 10);
  EXPECT_EQ(st.image_not_responding, 0u);
  EXPECT_EQ(st.limit_violations, 0u);
}

// The deadline watchdog in the node, on a fixed simulated clock, the loop driver's calls
// made by hand: cycles that overran (work ending 1.2 ms after a 1 ms deadline) and one
// wake-up 60 ms late. K = 5 consecutive overruns hold the tip where it is while the target
// keeps moving (its setpoint moves 0.3 mm in those 25 ms at t = 1.5 s: 2 mm · 2π rad/s);
// 200 on-time cycles end the hold; a 60 ms outage (> retract_after_s = 50 ms) retracts,
// latched through fresh estimates (auto_enable does not resume) until an ENABLE.
TEST(ServoNodeDeadlines, OverrunsHoldTheTipAnOutageRetractsAndAnEnableClears) {
  ServoNodeOptions o;
  o.follower.standoff_mm = 3.0;
  o.auto_enable = true;
  o.watchdog.hold_after_overruns = 5;
  o.watchdog.retract_after_s = 0.05;
  o.watchdog.resume_after_on_time = 200;
  Rig rig(o);
  std::uint64_t seq = 0;
  // One cycle as ServoCycleClock drives it: wake `late_s` after the deadline, work, end.
  auto step = [&](double late_s, bool overran) {
    if (rig.k % 40 == 0) rig.node.HandleTarget(Estimate(rig.t(), ++seq, rig.Tip()), rig.t());
    const double t = rig.t();
    rig.node.NoteWake(t, late_s);
    const ServoCycle c = rig.Step();
    rig.node.NoteCycleEnd(t + (overran ? 1.2e-3 : 0.3e-3), overran);
    return c;
  };
  auto target_setpoint = [](double t) { return 10.0 + 2.0 * std::sin(2 * M_PI * t) - 3.0; };
  ServoCycle c;
  while (rig.t() < 1.5) c = step(0.0, false);
  ASSERT_EQ(c.mode, link::ServoMode::kTracking);

  // K − 1 overruns: still following.
  for (int i = 0; i < 4; ++i) EXPECT_EQ(step(0.0, true).mode, link::ServoMode::kTracking);
  // The K-th: the hold is in force from the next cycle on.
  step(0.0, true);
  const double hold_start_s = rig.t();
  c = step(0.0, true);
  ASSERT_EQ(c.mode, link::ServoMode::kHolding);
  EXPECT_TRUE(c.faults & link::fault::kDeadlineHold);
  EXPECT_TRUE(rig.node.State(rig.t()).faults & link::fault::kDeadlineHold);
  const double held_mm = c.record.reference_mm;
  double max_dev_mm = 0.0;
  while (rig.t() < hold_start_s + 0.025) {  // still overrunning, 30 ms in all (< 50 ms)
    c = step(0.0, true);
    ASSERT_EQ(c.mode, link::ServoMode::kHolding);
    max_dev_mm = std::max(max_dev_mm, std::abs(c.record.reference_mm - held_mm));
  }
  EXPECT_LE(max_dev_mm, 0.05);
  EXPECT_GT(std::abs(target_setpoint(rig.t()) - target_setpoint(hold_start_s)), 0.2);
  EXPECT_EQ(rig.node.stats().deadline_holds, 1u);
  EXPECT_EQ(rig.node.stats().deadline_retracts, 0u);

  // On time again: the hold ends after resume_after_on_time cycles, following resumes.
  int on_time = 0;
  do {
    c = step(0.0, false);
    ++on_time;
  } while (c.mode != link::ServoMode::kTracking && on_time < 400);
  EXPECT_GE(on_time, 200);
  EXPECT_LE(on_time, 202);
  EXPECT_FALSE(c.faults & link::fault::kDeadlineHold);
  while (rig.t() < 2.5) c = step(0.0, false);
  EXPECT_EQ(c.mode, link::ServoMode::kTracking);
  EXPECT_NEAR(c.record.reference_mm, target_setpoint(rig.t()), 0.05);

  // An outage: the cycle due now wakes 60 ms late (the loop skips the missed cycles).
  rig.k += 60;
  c = step(0.060, false);
  c = step(0.0, false);
  ASSERT_EQ(c.mode, link::ServoMode::kRetracting);
  EXPECT_TRUE(c.faults & link::fault::kDeadlineRetract);
  EXPECT_TRUE(rig.node.State(rig.t()).faults & link::fault::kDeadlineRetract);
  EXPECT_EQ(rig.node.stats().deadline_retracts, 1u);
  const double retract_from_mm = c.record.reference_mm;
  const double retract_start_s = rig.t();
  while (rig.t() < retract_start_s + 0.1) {  // estimates keep coming: no auto-resume
    c = step(0.0, false);
    ASSERT_EQ(c.mode, link::ServoMode::kRetracting);
  }
  // Back at retract_speed_mm_s = 20 mm/s: 2 mm in 0.1 s (a cycle either side).
  EXPECT_NEAR(retract_from_mm - c.record.reference_mm, 2.0, 0.05);
  EXPECT_EQ(rig.node.stats().resumes, 0u);

  // The operator's ENABLE (through the command queue) clears it: following again.
  rig.node.EnqueueCommand(Command(link::ServoAction::kEnable, rig.t(), 3.0));
  while (rig.t() < retract_start_s + 0.2) c = step(0.0, false);
  EXPECT_EQ(c.mode, link::ServoMode::kTracking);
  EXPECT_FALSE(c.faults & (link::fault::kDeadlineHold | link::fault::kDeadlineRetract));
  EXPECT_EQ(rig.node.watchdog().action(), control::DeadlineAction::kNone);
  EXPECT_EQ(rig.node.stats().limit_violations, 0u);
}

TEST(ServoNodeDeadlines, BadWatchdogOptionsThrowNamingTheOption) {
  auto message = [](control::DeadlineWatchdogConfig w) {
    ServoNodeOptions o;
    o.watchdog = w;
    try {
      Rig rig(o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  control::DeadlineWatchdogConfig zero;
  zero.hold_after_overruns = 0;
  EXPECT_NE(message(zero).find("--deadline-hold-after"), std::string::npos) << message(zero);
  control::DeadlineWatchdogConfig early;  // retraction before the hold: 5 ms ≤ 10 · 1 ms
  early.hold_after_overruns = 10;
  early.retract_after_s = 0.005;
  EXPECT_NE(message(early).find("--deadline-retract-after-ms"), std::string::npos)
      << message(early);
}

// Commands queued from another thread (the command subscriber's path): a STOP drops what
// was queued before it and is applied in the next cycle; what follows it still applies,
// in order; a STOP followed by more commands than the queue holds, within one cycle, still
// stops (and the overwritten ones are counted).
TEST(ServoNode, AQueuedStopOvertakesTheCommandsQueuedBeforeIt) {
  ServoNodeOptions o;
  o.follower.standoff_mm = 3.0;
  o.auto_enable = true;
  Rig rig(o);
  std::uint64_t seq = 0;
  ServoCycle c = rig.RunUntil(1.0, true, &seq);
  ASSERT_EQ(c.mode, link::ServoMode::kTracking);
  std::uint64_t applied = rig.node.stats().commands_applied;
  rig.node.EnqueueCommand(Command(link::ServoAction::kSetStandoff, rig.t(), 6.0));
  rig.node.EnqueueCommand(Command(link::ServoAction::kStop, rig.t()));
  c = rig.Step();
  EXPECT_EQ(c.mode, link::ServoMode::kStopped);
  EXPECT_DOUBLE_EQ(rig.node.follower().config().standoff_mm, 3.0);  // dropped by the STOP
  EXPECT_EQ(rig.node.stats().commands_applied, applied + 1);

  rig.node.EnqueueCommand(Command(link::ServoAction::kStop, rig.t()));
  rig.node.EnqueueCommand(Command(link::ServoAction::kEnable, rig.t(), 4.0));
  rig.Step();
  EXPECT_DOUBLE_EQ(rig.node.follower().config().standoff_mm, 4.0);
  EXPECT_EQ(rig.node.stats().commands_applied, applied + 3);
  c = rig.RunUntil(rig.t() + 0.2, true, &seq);
  ASSERT_EQ(c.mode, link::ServoMode::kTracking);

  applied = rig.node.stats().commands_applied;
  rig.node.EnqueueCommand(Command(link::ServoAction::kStop, rig.t()));
  const std::size_t more = ServoNode::kMaxQueuedCommands + 6;
  for (std::size_t i = 0; i < more; ++i)
    rig.node.EnqueueCommand(Command(link::ServoAction::kSetStandoff, rig.t(), 5.0));
  c = rig.Step();
  EXPECT_EQ(c.mode, link::ServoMode::kStopped);
  EXPECT_EQ(rig.node.stats().commands_dropped, 7u);  // the STOP and the 6 oldest after it
  EXPECT_EQ(rig.node.stats().commands_applied, applied + ServoNode::kMaxQueuedCommands + 1);
  EXPECT_DOUBLE_EQ(rig.node.follower().config().standoff_mm, 5.0);
  EXPECT_EQ(rig.node.commands_queued(), 4 + more + 1);
  EXPECT_EQ(rig.node.stats().limit_violations, 0u);
}

}  // namespace
}  // namespace echoservo::live
