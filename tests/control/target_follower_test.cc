// The live servo's reference (control/target_follower.h): following the predicted target at a
// standoff, the image↔catheter offset, the stale-estimate watchdog, stop, and rejection of bad
// estimates.
#include "control/target_follower.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace echoservo::control {
namespace {

// Target along the axis: 40 mm + 5 mm·cos(2π·1.2·t); valid for 0.5 s after acquisition.
TargetEstimateInput Estimate(double acquired_s, double tip_axis_mm,
                             double published_delay_s = 0.06) {
  TargetEstimateInput e;
  e.acquired_s = acquired_s;
  e.published_s = acquired_s + published_delay_s;
  e.target_motion.t0_s = 0.0;
  e.target_motion.frequency_hz = 1.2;
  e.target_motion.offset_mm = 40.0;
  e.target_motion.cos_mm = {5.0};
  e.target_motion.sin_mm = {0.0};
  e.target_motion.valid_until_s = acquired_s + 0.5;
  e.tip_axis_mm = tip_axis_mm;
  e.confidence = 0.9;
  return e;
}

double Target(double t) { return 40.0 + 5.0 * std::cos(2 * std::numbers::pi * 1.2 * t); }

TEST(TargetFollower, FollowsThePredictedTargetAtTheStandoffInCatheterCoordinates) {
  FollowerConfig c;
  c.standoff_mm = 3.0;
  TargetFollower f(c);
  // The tip sits at x = 2 mm (catheter) while the image sees it at s = 32 mm: c = 30 mm.
  for (double t = 0.0; t < 0.1; t += 0.001) f.Update(t, 2.0);
  f.Enable(0.1);
  ASSERT_TRUE(f.Accept(Estimate(0.05, 32.0), 0.11));
  f.Update(0.111, 2.0);
  EXPECT_EQ(f.mode(), FollowerMode::kFollowing);
  EXPECT_NEAR(f.offset_mm(), 30.0, 1e-9);
  for (double t : {0.12, 0.2, 0.3}) {
    const MotionSample m = f.Evaluate(t);
    EXPECT_NEAR(m.position_mm, Target(t) - 3.0 - 30.0, 1e-9) << t;
    EXPECT_NEAR(m.velocity_mm_s,
                -5.0 * 2 * std::numbers::pi * 1.2 * std::sin(2 * std::numbers::pi * 1.2 * t), 1e-6);
  }
  f.SetStandoff(5.0);
  EXPECT_NEAR(f.Evaluate(0.2).position_mm, Target(0.2) - 5.0 - 30.0, 1e-9);
  EXPECT_THROW(f.SetStandoff(-1.0), std::invalid_argument);
  EXPECT_THROW(f.SetStandoff(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
}

TEST(TargetFollower, OffsetIsMeasuredAgainstTheTipAtAcquisitionAndLowPassed) {
  FollowerConfig c;
  c.offset_gain = 0.5;
  TargetFollower f(c);
  // The tip moves x = t (mm) for t in s; the estimate acquired at 0.5 s saw it at s = 10.5.
  for (double t = 0.0; t <= 0.6; t += 0.001) f.Update(t, t);
  f.Enable(0.6);
  ASSERT_TRUE(f.Accept(Estimate(0.5, 10.5), 0.6));
  EXPECT_NEAR(f.offset_mm(), 10.0, 1e-6);
  for (double t = 0.601; t <= 0.7; t += 0.001) f.Update(t, t);
  ASSERT_TRUE(f.Accept(Estimate(0.6, 0.6 + 10.0 + 1.0), 0.7));  // 1 mm more: half of it is taken
  EXPECT_NEAR(f.offset_mm(), 10.5, 1e-6);
}

// The image sees catheter millimetres scaled by k (a sound-speed mismatch: 1540/1482 in
// water): s_tip = k·x_tip + c. The fitted slope approaches k within the prior's pull,
// k − (k − 1)·λ/(var(x) + λ), and the reference is x = (s_target − standoff − c)/k.
TEST(TargetFollower, EstimatesTheImageToCatheterScale) {
  const double k = 1540.0 / 1482.0, c0 = 30.0, amp = 3.0, f = 1.0;
  FollowerConfig cfg;
  cfg.standoff_mm = 3.0;
  cfg.estimate_scale = true;
  TargetFollower follower(cfg);
  TargetFollower plain(FollowerConfig{.standoff_mm = 3.0});
  EXPECT_EQ(follower.scale(), 1.0);
  auto tip = [&](double t) { return amp * std::sin(2 * std::numbers::pi * f * t); };
  double t = 0.0;
  bool enabled = false;
  // 40 s of volumes at 25 Hz, the tip moving ±3 mm at 1 Hz.
  for (int j = 0; j < 1000; ++j) {
    const double acquired = 0.04 * j;
    for (; t < acquired + 0.06; t += 0.001) {
      follower.Update(t, tip(t));
      plain.Update(t, tip(t));
    }
    ASSERT_TRUE(follower.Accept(Estimate(acquired, k * tip(acquired) + c0), t));
    ASSERT_TRUE(plain.Accept(Estimate(acquired, k * tip(acquired) + c0), t));
    if (!enabled) {
      follower.Enable(t);
      plain.Enable(t);
      enabled = true;
    }
  }
  EXPECT_EQ(plain.scale(), 1.0);
  // The prior's pull: λ = σ²/(n_eff·σ_k²) with n_eff = (2 − g)/g, var(x) = amp²/2.
  const double g = cfg.scale_gain;
  const double lambda =
      cfg.tip_noise_mm * cfg.tip_noise_mm / ((2 - g) / g * cfg.scale_prior_sd * cfg.scale_prior_sd);
  const double expected = k - (k - 1) * lambda / (amp * amp / 2 + lambda);
  EXPECT_NEAR(follower.scale(), expected, 0.002);
  // The reference makes the image see the tip at s_target − standoff: k·x_ref + c0.
  double worst = 0.0, worst_plain = 0.0;
  for (double te = t; te < t + 0.2; te += 0.01) {
    const double want = Target(te) - 3.0;
    worst = std::max(worst, std::abs(k * follower.Evaluate(te).position_mm + c0 - want));
    worst_plain = std::max(worst_plain, std::abs(k * plain.Evaluate(te).position_mm + c0 - want));
  }
  // Within the slope's residual error times the target's distance from the tip's mean.
  EXPECT_LT(worst, 0.05);
  // Uncorrected (k = 1): (k − 1)·(s_target − standoff − c0), 0.2–0.45 mm over this window.
  EXPECT_GT(worst_plain, 0.3);
}

TEST(TargetFollower, StaleEstimateHoldsThenRetractsAndAFreshOneResumes) {
  FollowerConfig c;
  c.stale_after_s = 0.2;
  c.retract_after_s = 0.3;
  c.retract_mm = 4.0;
  c.retract_speed_mm_s = 20.0;
  TargetFollower f(c);
  f.Update(0.0, 1.0);
  f.Enable(0.0);
  ASSERT_TRUE(f.Accept(Estimate(0.0, 31.0, 0.0), 0.0));
  double t = 0.0;
  for (; t < 0.2 - 1e-9; t += 0.001) {
    f.Update(t, 1.0);
    EXPECT_EQ(f.mode(), FollowerMode::kFollowing) << t;
  }
  // The first cycle past the watchdog holds the tip where it is.
  f.Update(0.2005, 1.25);
  EXPECT_EQ(f.mode(), FollowerMode::kHolding);
  EXPECT_TRUE(f.faults() & follower_fault::kStaleEstimate);
  EXPECT_DOUBLE_EQ(f.Evaluate(0.2005).position_mm, 1.25);
  // Retraction after retract_after_s, at retract_speed, by retract_mm.
  for (t = 0.201; t < 0.5; t += 0.001) f.Update(t, 1.25);
  f.Update(0.5006, 1.25);
  EXPECT_EQ(f.mode(), FollowerMode::kRetracting);
  EXPECT_NEAR(f.Evaluate(0.6005).position_mm, 1.25 - 20.0 * 0.1, 1e-6);
  EXPECT_NEAR(f.Evaluate(5.0).position_mm, 1.25 - 4.0, 1e-12);
  // A fresh estimate and Enable resume following.
  ASSERT_TRUE(f.Accept(Estimate(0.95, 31.0, 0.01), 1.0));
  f.Enable(1.0);
  f.Update(1.001, 1.0);
  EXPECT_EQ(f.mode(), FollowerMode::kFollowing);
  EXPECT_EQ(f.counters().stale_events, 1u);
}

TEST(TargetFollower, StopHoldsWithinTheCycleAndIgnoresNewEstimatesUntilEnabled) {
  TargetFollower f(FollowerConfig{});
  f.Update(0.0, 0.0);
  f.Enable(0.0);
  ASSERT_TRUE(f.Accept(Estimate(0.0, 30.0, 0.0), 0.0));
  f.Update(0.05, 0.7);
  f.Stop(0.05);
  EXPECT_EQ(f.mode(), FollowerMode::kStopped);
  EXPECT_DOUBLE_EQ(f.Evaluate(0.051).position_mm, 0.7);
  EXPECT_TRUE(f.Accept(Estimate(0.06, 30.0, 0.0), 0.07));
  f.Update(0.08, 0.7);
  EXPECT_EQ(f.mode(), FollowerMode::kStopped);
  EXPECT_DOUBLE_EQ(f.Evaluate(0.08).position_mm, 0.7);
}

TEST(TargetFollower, BadEstimatesAreRejectedAndCounted) {
  TargetFollower f(FollowerConfig{});
  f.Update(1.0, 0.0);
  f.Enable(1.0);
  auto nan = Estimate(0.9, 30.0);
  nan.target_motion.cos_mm[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(f.Accept(nan, 1.0));
  auto inf_tip = Estimate(0.9, std::numeric_limits<double>::infinity());
  EXPECT_FALSE(f.Accept(inf_tip, 1.0));
  EXPECT_EQ(f.counters().rejected_non_finite, 2u);
  auto far = Estimate(0.9, 30.0);
  far.target_motion.offset_mm = 5000.0;
  EXPECT_FALSE(f.Accept(far, 1.0));
  auto mismatched = Estimate(0.9, 30.0);
  mismatched.target_motion.sin_mm.push_back(1.0);
  EXPECT_FALSE(f.Accept(mismatched, 1.0));
  EXPECT_EQ(f.counters().rejected_range, 2u);
  EXPECT_FALSE(f.Accept(Estimate(1.5, 30.0), 1.0));  // from the future
  auto reversed = Estimate(0.9, 30.0);
  reversed.published_s = 0.8;  // published before acquired
  EXPECT_FALSE(f.Accept(reversed, 1.0));
  EXPECT_FALSE(f.Accept(Estimate(-5.0, 30.0), 1.0));  // far too old
  EXPECT_EQ(f.counters().rejected_time, 3u);
  auto unsure = Estimate(0.9, 30.0);
  unsure.confidence = 0.1;
  EXPECT_FALSE(f.Accept(unsure, 1.0));
  EXPECT_EQ(f.counters().rejected_confidence, 1u);
  EXPECT_TRUE(f.Accept(Estimate(0.9, 30.0), 1.0));
  EXPECT_FALSE(f.Accept(Estimate(0.9, 30.0), 1.0));  // not newer than the last
  EXPECT_EQ(f.counters().accepted, 1u);
  EXPECT_EQ(f.mode(), FollowerMode::kFollowing);
}

TEST(TargetFollower, ReferenceIsClampedToTheTravelLimits) {
  FollowerConfig c;
  c.travel_min_mm = -2.0;
  c.travel_max_mm = 2.0;
  TargetFollower f(c);
  f.Update(0.0, 0.0);
  f.Enable(0.0);
  ASSERT_TRUE(f.Accept(Estimate(0.0, 0.0, 0.0), 0.0));  // offset 0: reference ≈ 37–42 mm
  const MotionSample m = f.Evaluate(0.01);
  EXPECT_DOUBLE_EQ(m.position_mm, 2.0);
  EXPECT_DOUBLE_EQ(m.velocity_mm_s, 0.0);
  EXPECT_TRUE(f.faults() & follower_fault::kTravelLimit);
}

TEST(TargetFollower, ConfigIsValidated) {
  FollowerConfig c;
  c.stale_after_s = 0.0;
  EXPECT_THROW(TargetFollower{c}, std::invalid_argument);
  c = {};
  c.travel_min_mm = 3.0;
  c.travel_max_mm = 1.0;
  EXPECT_THROW(TargetFollower{c}, std::invalid_argument);
  for (double bad : {0.0, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    c = {};
    c.scale_gain = bad;
    EXPECT_THROW(TargetFollower{c}, std::invalid_argument) << bad;
    c = {};
    c.scale_prior_sd = bad;
    EXPECT_THROW(TargetFollower{c}, std::invalid_argument) << bad;
  }
  c = {};
  c.tip_noise_mm = -0.1;
  EXPECT_THROW(TargetFollower{c}, std::invalid_argument);
}

}  // namespace
}  // namespace echoservo::control
