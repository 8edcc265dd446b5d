// Backlash compensators: the identity, the static inverse deadzone and its reversal
// lead, the iterative (learning) table, and the online adaptive inverse against a
// synthetic deadzone + lag plant written here (independent of hw/).
#include "control/backlash_compensation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "control/trajectory.h"
#include "tests/test_util/constants.h"

namespace echoservo::control {
namespace {

using testing::kDt;
using testing::kNaN;

CompensatorInput At(const Trajectory& reference, std::size_t k, double tip = 0.0) {
  return {.t_s = static_cast<double>(k) * kDt,
          .cycle = k,
          .period_s = kDt,
          .reference = &reference,
          .tip_measured_mm = tip};
}

TEST(NoCompensationTest, ReturnsTheReference) {
  const SineTrajectory sine(5.0, 1.0);
  NoCompensation none;
  EXPECT_EQ(none.name(), "none");
  for (std::size_t k = 0; k < 2000; k += 37) {
    const BaseCommand c = none.Calc(At(sine, k, 123.0));
    const MotionSample r = sine.Evaluate(static_cast<double>(k) * kDt);
    EXPECT_EQ(c.position_mm, r.position_mm);
    EXPECT_EQ(c.velocity_mm_s, r.velocity_mm_s);
  }
}

TEST(DirectionTrackerTest, SwitchesOnceOutsideTheDeadBand) {
  DirectionTracker d(0.5);
  bool switched = true;
  EXPECT_EQ(d.Update(0.4, &switched), 0.0);  // not yet moved
  EXPECT_FALSE(switched);
  EXPECT_EQ(d.Update(0.6, &switched), 1.0);
  EXPECT_FALSE(switched);                     // the first direction is not a switch
  EXPECT_EQ(d.Update(-0.4, &switched), 1.0);  // inside the dead band: keep
  EXPECT_FALSE(switched);
  EXPECT_EQ(d.Update(-0.6, &switched), -1.0);
  EXPECT_TRUE(switched);
  EXPECT_EQ(d.Update(-5.0, &switched), -1.0);
  EXPECT_FALSE(switched);
  d.Reset();
  EXPECT_EQ(d.Update(0.0, &switched), 0.0);
}

TEST(StaticInverseTest, LeadIsHalfABangBangCrossing) {
  for (double w : {0.0, 0.25, 1.0, 2.5, 4.0}) {
    for (double a : {1000.0, 60000.0}) {
      EXPECT_NEAR(StaticInverse(w, a).lead_s(), std::sqrt(w / a), 1e-15) << w << " " << a;
    }
  }
}

// base = r + s·W/2: +W/2 while the reference moves up, −W/2 while it moves down, and
// the switch comes `lead` = √(W/a_max) before the reference velocity (ahead) crosses
// the tracker's −0.5 mm/s dead band, i.e. before the reversal.
TEST(StaticInverseTest, AddsHalfWidthInTheDirectionOfMotionAndSwitchesEarly) {
  const double amp = 5.0, f = 1.0, w = 2.0 * std::numbers::pi * f;
  const SineTrajectory sine(amp, f);
  for (double width : {1.0, 2.5, 4.0}) {
    StaticInverse inv(width, 60000.0);
    EXPECT_EQ(inv.name(), "inverse");
    inv.Reset();
    const double lead = std::sqrt(width / 60000.0);
    // The reference velocity A·ω·cos(ωt) crosses −0.5 mm/s (down) just after the
    // reversal at t = 0.25 s, and +0.5 mm/s (up) just after t = 0.75 s.
    const double t_down = std::acos(-0.5 / (amp * w)) / w;
    const double t_up = (2.0 * std::numbers::pi - std::acos(0.5 / (amp * w))) / w;
    double switch_down = -1.0, switch_up = -1.0;
    double prev_s = 0.0;
    for (std::size_t k = 0; k < 1000; ++k) {
      const double t = static_cast<double>(k) * kDt;
      const BaseCommand c = inv.Calc(At(sine, k));
      const MotionSample r = sine.Evaluate(t);
      const double s = (c.position_mm - r.position_mm) / (0.5 * width);
      ASSERT_NEAR(std::abs(s), 1.0, 1e-9) << "t=" << t;  // always ±W/2 (the sine starts moving)
      EXPECT_EQ(c.velocity_mm_s, r.velocity_mm_s);
      if (k > 0 && s < 0.0 && prev_s > 0.0) switch_down = t;
      if (k > 0 && s > 0.0 && prev_s < 0.0) switch_up = t;
      // Away from the switches, the sign is the direction of motion.
      if (std::abs(std::cos(w * t)) > 0.1) {
        EXPECT_EQ(s > 0.0, r.velocity_mm_s > 0.0) << "t=" << t;
      }
      prev_s = s;
    }
    ASSERT_GT(switch_down, 0.0);
    ASSERT_GT(switch_up, 0.0);
    EXPECT_NEAR(switch_down, t_down - lead, kDt) << "width " << width;
    EXPECT_NEAR(switch_up, t_up - lead, kDt) << "width " << width;
    EXPECT_LT(switch_down, 0.25 + 1e-12);  // before the reversal itself
    EXPECT_LT(switch_up, 0.75 + 1e-12);
  }
}

TEST(StaticInverseTest, ZeroWidthIsTheIdentity) {
  const SineTrajectory sine(5.0, 1.0);
  StaticInverse inv(0.0, 60000.0);
  for (std::size_t k = 0; k < 1000; k += 7) {
    EXPECT_EQ(inv.Calc(At(sine, k)).position_mm,
              sine.Evaluate(static_cast<double>(k) * kDt).position_mm);
  }
}

// A time advance τ reads the reference τ ahead: base = r(t + τ) ± W/2, velocity ṙ(t + τ), and
// the direction switches τ earlier too.
TEST(StaticInverseTest, TimeAdvanceReadsTheReferenceAhead) {
  const SineTrajectory sine(5.0, 1.0);
  const double width = 1.0, tau = 0.008;
  StaticInverse plain(width, 60000.0), ahead(width, 60000.0, tau);
  EXPECT_EQ(ahead.time_advance_s(), tau);
  EXPECT_EQ(plain.time_advance_s(), 0.0);
  const auto step = static_cast<std::size_t>(std::llround(tau / kDt));
  std::vector<BaseCommand> p, a;
  for (std::size_t k = 0; k < 1000 + step; ++k) {
    p.push_back(plain.Calc(At(sine, k)));
    if (k < 1000) a.push_back(ahead.Calc(At(sine, k)));
  }
  // From the first motion on, the advanced command at cycle k is the plain one at k + τ/dt.
  for (std::size_t k = 10; k < 1000; ++k) {
    EXPECT_NEAR(a[k].position_mm, p[k + step].position_mm, 1e-9) << k;
    EXPECT_NEAR(a[k].velocity_mm_s, p[k + step].velocity_mm_s, 1e-9) << k;
  }
}

TEST(StaticInverseTest, RejectsInvalidArguments) {
  EXPECT_THROW(StaticInverse(1.0, 60000.0, -0.001), std::invalid_argument);
  EXPECT_THROW(StaticInverse(1.0, 60000.0, 0.2), std::invalid_argument);
  EXPECT_THROW(StaticInverse(1.0, 60000.0, kNaN), std::invalid_argument);
  EXPECT_THROW(StaticInverse(-0.1, 60000.0), std::invalid_argument);
  EXPECT_THROW(StaticInverse(kNaN, 60000.0), std::invalid_argument);
  EXPECT_THROW(StaticInverse(1.0, 0.0), std::invalid_argument);
  EXPECT_THROW(StaticInverse(1.0, -1.0), std::invalid_argument);
  EXPECT_THROW(StaticInverse(1.0, kNaN), std::invalid_argument);
}

TEST(IterativeInverseTest, LearnAccumulatesGainTimesError) {
  IterativeInverse ilc(IterativeOptions{.learning_gain = 0.5});
  EXPECT_EQ(ilc.name(), "iterative");
  EXPECT_TRUE(ilc.correction_mm().empty());
  ilc.Learn({1.0, 2.0, -3.0});
  ASSERT_EQ(ilc.correction_mm().size(), 3u);
  EXPECT_DOUBLE_EQ(ilc.correction_mm()[0], 0.5);
  EXPECT_DOUBLE_EQ(ilc.correction_mm()[1], 1.0);
  EXPECT_DOUBLE_EQ(ilc.correction_mm()[2], -1.5);
  ilc.Learn({1.0, 1.0});  // shorter run: the tail is kept
  ASSERT_EQ(ilc.correction_mm().size(), 3u);
  EXPECT_DOUBLE_EQ(ilc.correction_mm()[0], 1.0);
  EXPECT_DOUBLE_EQ(ilc.correction_mm()[1], 1.5);
  EXPECT_DOUBLE_EQ(ilc.correction_mm()[2], -1.5);
  ilc.Learn({0.0, 0.0, 0.0, 4.0});  // longer run: the table grows
  ASSERT_EQ(ilc.correction_mm().size(), 4u);
  EXPECT_DOUBLE_EQ(ilc.correction_mm()[3], 2.0);
}

// A rejected learning step must leave the table as it was (no partial update).
TEST(IterativeInverseTest, LearnRejectsNonFiniteErrors) {
  IterativeInverse ilc;
  ilc.Learn({0.1, 0.2});
  const std::vector<double> before = ilc.correction_mm();
  EXPECT_THROW(ilc.Learn({1.0, kNaN, 1.0}), std::invalid_argument);
  EXPECT_THROW(ilc.Learn({1.0, 1.0, std::numeric_limits<double>::infinity()}),
               std::invalid_argument);
  EXPECT_EQ(ilc.correction_mm(), before);
}

TEST(IterativeInverseTest, CalcAddsTheCorrectionAndItsSlope) {
  const SineTrajectory sine(5.0, 1.0);
  IterativeInverse ilc;
  ilc.Learn({0.0, 0.1, 0.3, 0.3});
  const double c[] = {0.0, 0.1, 0.3, 0.3};
  for (std::size_t k = 0; k < 6; ++k) {
    const BaseCommand cmd = ilc.Calc(At(sine, k));
    const MotionSample r = sine.Evaluate(static_cast<double>(k) * kDt);
    const double ck = k < 4 ? c[k] : 0.0;
    const double slope = k + 1 < 4 ? (c[k + 1] - c[k]) / kDt : 0.0;
    EXPECT_NEAR(cmd.position_mm, r.position_mm + ck, 1e-12) << k;
    EXPECT_NEAR(cmd.velocity_mm_s, r.velocity_mm_s + slope, 1e-9) << k;
  }
}

// Against a pure offset plant (tip = base − 0.3 mm), one learning pass with gain 1
// removes the error exactly: P-type learning inverts a static plant in one step.
TEST(IterativeInverseTest, OneUnitGainPassCancelsAStaticOffset) {
  const SineTrajectory sine(5.0, 1.0);
  IterativeInverse ilc;
  auto run = [&] {
    std::vector<double> err;
    for (std::size_t k = 0; k < 500; ++k) {
      const double base = ilc.Calc(At(sine, k)).position_mm;
      err.push_back(sine.Evaluate(static_cast<double>(k) * kDt).position_mm - (base - 0.3));
    }
    return err;
  };
  const std::vector<double> first = run();
  for (double e : first) ASSERT_NEAR(e, 0.3, 1e-12);
  ilc.Learn(first);
  for (double e : run()) ASSERT_NEAR(e, 0.0, 1e-12);
}

TEST(IterativeInverseTest, RejectsInvalidGain) {
  for (double g : {0.0, -0.5, 2.01, kNaN}) {
    EXPECT_THROW(IterativeInverse(IterativeOptions{.learning_gain = g}), std::invalid_argument)
        << g;
  }
  EXPECT_NO_THROW(IterativeInverse(IterativeOptions{.learning_gain = 2.0}));
}

// A synthetic catheter: the base follows the command exactly (an ideal servo, zero-
// order hold over each period); the tip sits in a deadzone band [base − W/2, base + W/2]
// and moves towards the band with a first-order lag τ; no noise.
struct DeadzoneLagPlant {
  double width_mm;
  double tau_s;
  double tip_mm = 0.0;
  void Step(double base_mm, double dt) {
    const double target = std::clamp(tip_mm, base_mm - 0.5 * width_mm, base_mm + 0.5 * width_mm);
    tip_mm += (target - tip_mm) * (1.0 - std::exp(-dt / tau_s));
  }
};

struct AdaptiveRun {
  double width = 0.0, lag = 0.0, offset = 0.0;
  std::vector<double> widths;  // per cycle
};

// Runs the adaptive inverse in closed loop with the synthetic plant; at cycle
// `outlier_cycle` the measured tip is off by `outlier_mm`.
AdaptiveRun RunAdaptive(AdaptiveOptions o, double w_true, double tau_true, double seconds,
                        std::size_t outlier_cycle = static_cast<std::size_t>(-1),
                        double outlier_mm = 0.0) {
  const SineTrajectory sine(5.0, 1.0);
  AdaptiveInverse comp(o);
  comp.Reset();
  DeadzoneLagPlant plant{w_true, tau_true};
  plant.tip_mm = sine.Evaluate(0.0).position_mm;
  AdaptiveRun run;
  const auto cycles = static_cast<std::size_t>(std::llround(seconds / kDt));
  for (std::size_t k = 0; k < cycles; ++k) {
    const double measured = plant.tip_mm + (k == outlier_cycle ? outlier_mm : 0.0);
    const BaseCommand c = comp.Calc(At(sine, k, measured));
    plant.Step(c.position_mm, kDt);
    run.widths.push_back(comp.width_mm());
  }
  run.width = comp.width_mm();
  run.lag = comp.lag_s();
  run.offset = comp.offset_mm();
  return run;
}

// The regression e = r − tip ≈ s·(W − Ŵ)/2 + (τ − τ̂)·ṙ + (o − ô) is exact for the
// synthetic plant up to second-order terms (the lag acting on τ̂·r̈, a 0.2% amplitude
// loss of the lag filter at 1 Hz) and the zero-order hold, which adds dt/2 = 0.5 ms to
// the apparent lag (5% of τ = 10 ms). Hence 5% on the width and 20% on the lag.
TEST(AdaptiveInverseTest, EstimatesConvergeOnASyntheticDeadzoneLagPlant) {
  const double w_true = 1.2, tau_true = 0.010;
  for (double initial : {0.0, 0.6, 2.0}) {
    AdaptiveOptions o;
    o.initial_width_mm = initial;
    const AdaptiveRun run = RunAdaptive(o, w_true, tau_true, 6.0);
    EXPECT_NEAR(run.width, w_true, 0.05 * w_true) << "initial width " << initial;
    EXPECT_NEAR(run.lag, tau_true, 0.2 * tau_true) << "initial width " << initial;
    EXPECT_NEAR(run.offset, 0.0, 0.05 * w_true) << "initial width " << initial;
  }
}

TEST(AdaptiveInverseTest, InnovationGateIgnoresASingleOutlier) {
  const double w_true = 1.2, tau_true = 0.010;
  AdaptiveOptions o;
  o.initial_width_mm = 0.6;
  // t = 5.000 s: the 1 Hz sine moves up at full speed, 0.25 s after its last reversal,
  // so the compensator is learning on this cycle.
  const std::size_t k = 5000;
  const AdaptiveRun clean = RunAdaptive(o, w_true, tau_true, 7.0);
  const AdaptiveRun outlier = RunAdaptive(o, w_true, tau_true, 7.0, k, 5.0);
  AdaptiveOptions ungated = o;
  ungated.innovation_gate_mm = 100.0;
  const AdaptiveRun ungated_clean = RunAdaptive(ungated, w_true, tau_true, 7.0);
  const AdaptiveRun ungated_outlier = RunAdaptive(ungated, w_true, tau_true, 7.0, k, 5.0);

  // Identical up to the outlier; on that cycle the clean run learns, the gated one not.
  EXPECT_EQ(outlier.widths[k - 1], clean.widths[k - 1]);
  EXPECT_NE(clean.widths[k], clean.widths[k - 1]);
  EXPECT_EQ(outlier.widths[k], outlier.widths[k - 1]);
  // Without the gate the same outlier moves the estimate far more than a clean step.
  const double clean_step = std::abs(ungated_clean.widths[k] - ungated_clean.widths[k - 1]);
  const double outlier_step = std::abs(ungated_outlier.widths[k] - ungated_outlier.widths[k - 1]);
  EXPECT_GT(outlier_step, 10.0 * clean_step);
  // The gated run still ends within 5% of the true width.
  EXPECT_NEAR(outlier.width, w_true, 0.05 * w_true);
}

TEST(AdaptiveInverseTest, NonFiniteTipIsNotLearnedFrom) {
  const SineTrajectory sine(5.0, 1.0);
  AdaptiveOptions o;
  o.initial_width_mm = 1.0;
  AdaptiveInverse comp(o);
  for (std::size_t k = 0; k < 3000; ++k) {
    const BaseCommand c = comp.Calc(At(sine, k, kNaN));
    ASSERT_TRUE(std::isfinite(c.position_mm));
    ASSERT_TRUE(std::isfinite(c.velocity_mm_s));
  }
  EXPECT_EQ(comp.width_mm(), 1.0);
  EXPECT_EQ(comp.lag_s(), 0.0);
  EXPECT_EQ(comp.offset_mm(), 0.0);
}

TEST(AdaptiveInverseTest, ResetRestoresTheInitialEstimates) {
  AdaptiveOptions o;
  o.initial_width_mm = 0.7;
  const SineTrajectory sine(5.0, 1.0);
  AdaptiveInverse comp(o);
  EXPECT_EQ(comp.name(), "adaptive");
  EXPECT_EQ(comp.width_mm(), 0.7);
  DeadzoneLagPlant plant{1.5, 0.01};
  for (std::size_t k = 0; k < 3000; ++k)
    plant.Step(comp.Calc(At(sine, k, plant.tip_mm)).position_mm, kDt);
  EXPECT_NE(comp.width_mm(), 0.7);
  comp.Reset();
  EXPECT_EQ(comp.width_mm(), 0.7);
  EXPECT_EQ(comp.lag_s(), 0.0);
  EXPECT_EQ(comp.offset_mm(), 0.0);
}

void ExpectInvalidOptions(const AdaptiveOptions& o, const std::string& field) {
  try {
    o.Validate();
    ADD_FAILURE() << "accepted invalid " << field;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
  EXPECT_THROW(AdaptiveInverse{o}, std::invalid_argument) << field;
}

TEST(AdaptiveInverseTest, OptionsValidationNamesTheField) {
  EXPECT_NO_THROW(AdaptiveOptions{}.Validate());
  const double inf = std::numeric_limits<double>::infinity();
  for (double bad : {-1.0, kNaN, inf}) {
    AdaptiveOptions o;
    o.initial_width_mm = bad;
    ExpectInvalidOptions(o, "initial_width_mm");
    o = AdaptiveOptions{};
    o.settle_after_reversal_s = bad;
    ExpectInvalidOptions(o, "settle_after_reversal_s");
    o = AdaptiveOptions{};
    o.min_speed_mm_s = bad;
    ExpectInvalidOptions(o, "min_speed_mm_s");
  }
  for (double bad : {0.0, -1.0, kNaN, inf}) {
    AdaptiveOptions o;
    o.max_acceleration_mm_s2 = bad;
    ExpectInvalidOptions(o, "max_acceleration_mm_s2");
    o = AdaptiveOptions{};
    o.initial_uncertainty = bad;
    ExpectInvalidOptions(o, "initial_uncertainty");
    o = AdaptiveOptions{};
    o.innovation_gate_mm = bad;
    ExpectInvalidOptions(o, "innovation_gate_mm");
  }
  for (double bad : {0.9, 0.5, 1.0001, kNaN}) {
    AdaptiveOptions o;
    o.forgetting = bad;
    ExpectInvalidOptions(o, "forgetting");
  }
  AdaptiveOptions o;
  o.forgetting = 1.0;
  EXPECT_NO_THROW(o.Validate());
}

}  // namespace
}  // namespace echoservo::control
