// "The controller never commands outside its limits (tests that try)."
//
// The limiter is driven with adversarial targets — ±1000 mm steps, NaN, ±inf, huge
// and non-finite target velocities — for thousands of cycles, and every setpoint it
// returns is checked against the limits it promises (control/command_limiter.h):
//   travel_min ≤ x_k ≤ travel_max,
//   |x_k − x_{k−1}|/dt ≤ v_max·(1 + 1e-9),
//   |v_k − v_{k−1}|/dt ≤ a_max·(1 + 1e-9),  v_k = (x_k − x_{k−1})/dt.
// The 1e-9 relative slack is the limiter's own comparison slack; the rounding of the
// differences themselves is ~ε·25 mm/dt² ≈ 5e-9 mm/s², 13 orders below a_max.
#include "control/command_limiter.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/test_util/constants.h"

namespace echoservo::control {
namespace {

using testing::kDt;
using testing::kNaN;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Drives a limiter and checks every setpoint against the limits.
class CheckedLimiter {
 public:
  explicit CheckedLimiter(Limits limits = {}) : limits_(limits), limiter_(limits, kDt) {}

  void Reset(double x) {
    limiter_.Reset(x);
    x_ = limiter_.setpoint_mm();
    v_ = 0.0;
  }

  double Step(double target, double target_velocity) {
    const double x = limiter_.Setpoint(target, target_velocity);
    ++cycle_;
    EXPECT_TRUE(std::isfinite(x)) << where(target, target_velocity);
    EXPECT_GE(x, limits_.travel_min_mm) << where(target, target_velocity);
    EXPECT_LE(x, limits_.travel_max_mm) << where(target, target_velocity);
    const double v = (x - x_) / kDt;
    EXPECT_LE(std::abs(v), limits_.max_velocity_mm_s * (1.0 + 1e-9))
        << where(target, target_velocity);
    EXPECT_LE(std::abs(v - v_) / kDt, limits_.max_acceleration_mm_s2 * (1.0 + 1e-9))
        << where(target, target_velocity) << " v " << v_ << " -> " << v;
    EXPECT_NEAR(limiter_.setpoint_velocity_mm_s(), v, 1e-9 * limits_.max_velocity_mm_s);
    EXPECT_EQ(limiter_.setpoint_mm(), x);
    x_ = x;
    v_ = v;
    return x;
  }

  CommandLimiter& limiter() { return limiter_; }
  double x() const { return x_; }
  double v() const { return v_; }
  bool failed() const { return ::testing::Test::HasFailure(); }

 private:
  std::string where(double target, double target_velocity) const {
    return "cycle " + std::to_string(cycle_) + " target " + std::to_string(target) + " mm at " +
           std::to_string(target_velocity) + " mm/s from x " + std::to_string(x_);
  }
  Limits limits_;
  CommandLimiter limiter_;
  double x_ = 0.0;
  double v_ = 0.0;
  long cycle_ = 0;
};

TEST(CommandLimiterTest, RandomAdversarialTargetsNeverLeaveTheLimits) {
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::uniform_real_distribution<double> big(-1000.0, 1000.0);
  std::uniform_real_distribution<double> travel(-24.4, 24.4);
  std::uniform_real_distribution<double> speed(-1e6, 1e6);
  CheckedLimiter c;
  c.Reset(0.0);
  std::uint64_t expected_non_finite = 0;
  std::uint64_t expected_travel = 0;
  double target = 0.0;
  double target_v = 0.0;
  for (int k = 0; k < 20000 && !c.failed(); ++k) {
    // Change the target every few cycles so the limiter also gets time to move.
    if (uni(rng) < 0.1) {
      const double p = uni(rng);
      if (p < 0.3) {
        target = big(rng);
      } else if (p < 0.6) {
        target = travel(rng);
      } else if (p < 0.7) {
        target = kNaN;
      } else if (p < 0.8) {
        target = uni(rng) < 0.5 ? kInf : -kInf;
      } else {
        target = uni(rng) < 0.5 ? 1000.0 : -1000.0;
      }
      const double q = uni(rng);
      target_v = q < 0.4   ? 0.0
                 : q < 0.8 ? speed(rng)
                 : q < 0.9 ? kNaN
                           : (uni(rng) < 0.5 ? kInf : -kInf);
    }
    const bool non_finite = !std::isfinite(target) || !std::isfinite(target_v);
    if (non_finite) {
      ++expected_non_finite;
    } else if (target < -24.4 || target > 24.4) {
      ++expected_travel;
    }
    c.Step(target, target_v);
  }
  const CommandLimiter& l = c.limiter();
  EXPECT_EQ(l.count(LimitEvent::kNonFinite), expected_non_finite);
  EXPECT_EQ(l.count(LimitEvent::kTravel), expected_travel);
  EXPECT_EQ(l.faults(), expected_non_finite + expected_travel);
  EXPECT_GT(l.count(LimitEvent::kVelocity), 0u);  // the test did push the limits
  EXPECT_GT(l.count(LimitEvent::kAcceleration), 0u);
}

// Targets inside travel with absurd target velocities: the target velocity is a hint,
// not a licence to run into the end stops.
TEST(CommandLimiterTest, HugeTargetVelocitiesNeverLeaveTheLimits) {
  std::mt19937_64 rng(777);
  std::uniform_real_distribution<double> travel(-24.4, 24.4);
  std::uniform_real_distribution<double> speed(-1e6, 1e6);
  CheckedLimiter c;
  c.Reset(0.0);
  for (int k = 0; k < 5000 && !c.failed(); ++k) {
    const double target = (k / 200) % 2 == 0 ? 0.0 : travel(rng);
    c.Step(target, (k / 100) % 2 == 0 ? 1e6 : speed(rng));
  }
  EXPECT_EQ(c.limiter().faults(), 0u);
}

// Alternating ±1000 mm steps: full-speed runs into the travel limits, each braking to
// a stop at the edge.
TEST(CommandLimiterTest, BangBangStepsBetweenTheTravelEndsStayWithinLimits) {
  CheckedLimiter c;
  c.Reset(0.0);
  for (int k = 0; k < 10000 && !c.failed(); ++k) {
    const double target = (k / 250) % 2 == 0 ? 1000.0 : -1000.0;
    c.Step(target, target > 0 ? 400.0 : -400.0);
  }
  EXPECT_EQ(c.limiter().count(LimitEvent::kTravel), 10000u);
  EXPECT_EQ(c.limiter().count(LimitEvent::kNonFinite), 0u);
}

TEST(CommandLimiterTest, NonFiniteTargetIsAFaultAndTheSetpointIsHeld) {
  CheckedLimiter c;
  c.Reset(3.0);
  for (double bad : {kNaN, kInf, -kInf}) {
    const double before = c.x();
    EXPECT_EQ(c.Step(bad, 0.0), before);
    EXPECT_EQ(c.Step(5.0, bad), before);  // a non-finite velocity rejects the sample too
  }
  EXPECT_EQ(c.limiter().count(LimitEvent::kNonFinite), 6u);
  EXPECT_EQ(c.limiter().faults(), 6u);
  EXPECT_EQ(c.limiter().setpoint_velocity_mm_s(), 0.0);
}

// While moving, a NaN target means "hold": the setpoint brakes at a_max (it cannot stop
// in zero time without breaking the acceleration limit) and then stays put.
TEST(CommandLimiterTest, NonFiniteTargetWhileMovingBrakesToAHold) {
  CheckedLimiter c;
  c.Reset(-20.0);
  for (int k = 0; k < 30; ++k) c.Step(20.0, 0.0);
  const double v0 = c.v();
  ASSERT_GT(v0, 100.0);
  // Braking distance from v0 at a_max is v0²/(2·a_max) plus at most one cycle's travel.
  const double x0 = c.x();
  int k = 0;
  for (; k < 100 && c.v() != 0.0; ++k) c.Step(kNaN, 0.0);
  EXPECT_EQ(c.v(), 0.0);
  EXPECT_LE(c.x() - x0, v0 * v0 / (2.0 * 60000.0) + v0 * kDt);
  EXPECT_LE(k, static_cast<int>(std::ceil(v0 / (60000.0 * kDt))) + 1);
  const double held = c.x();
  for (int j = 0; j < 50; ++j) EXPECT_EQ(c.Step(kNaN, kNaN), held);
}

TEST(CommandLimiterTest, TravelViolationsAreFaultsAndClamped) {
  CheckedLimiter c;
  c.Reset(0.0);
  for (int k = 0; k < 400; ++k) c.Step(30.0, 0.0);
  EXPECT_EQ(c.x(), 24.4);
  EXPECT_EQ(c.limiter().count(LimitEvent::kTravel), 400u);
  for (int k = 0; k < 400; ++k) c.Step(-1000.0, 0.0);
  EXPECT_EQ(c.x(), -24.4);
  EXPECT_EQ(c.limiter().count(LimitEvent::kTravel), 800u);
  EXPECT_EQ(c.limiter().faults(), 800u);
  // Inside travel: no travel event.
  c.Step(-24.4, 0.0);
  EXPECT_EQ(c.limiter().count(LimitEvent::kTravel), 800u);
}

TEST(CommandLimiterTest, ResetClampsIntoTravel) {
  CommandLimiter l(Limits{}, kDt);
  l.Reset(100.0);
  EXPECT_EQ(l.setpoint_mm(), 24.4);
  l.Reset(-100.0);
  EXPECT_EQ(l.setpoint_mm(), -24.4);
  l.Reset(kNaN);
  EXPECT_EQ(l.setpoint_mm(), 0.0);
  EXPECT_EQ(l.setpoint_velocity_mm_s(), 0.0);
}

// The minimum time to move d from rest to rest: a trapezoid if d ≥ v²/a, else a
// triangle.
double MinimumTime(double d, double v, double a) {
  return d >= v * v / a ? d / v + v / a : 2.0 * std::sqrt(d / a);
}

TEST(CommandLimiterTest, ReachableStepTargetIsReachedWithoutOvershoot) {
  const Limits limits;
  struct Case {
    double from, to;
  };
  for (const Case& cs : {Case{0.0, 10.0}, Case{5.0, -15.0}, Case{0.0, 0.05}, Case{-24.4, 24.4},
                         Case{1.0, 1.7}, Case{24.4, -3.0}}) {
    CheckedLimiter c(limits);
    c.Reset(cs.from);
    const double dir = cs.to > cs.from ? 1.0 : -1.0;
    const double t_min = MinimumTime(std::abs(cs.to - cs.from), limits.max_velocity_mm_s,
                                     limits.max_acceleration_mm_s2);
    int reached = -1;
    double prev = cs.from;
    for (int k = 1; k <= 1000; ++k) {
      const double x = c.Step(cs.to, 0.0);
      ASSERT_LE(dir * (x - cs.to), 1e-12)
          << cs.from << "->" << cs.to << " overshoot at cycle " << k;
      ASSERT_GE(dir * (x - prev), -1e-12)
          << cs.from << "->" << cs.to << " moved backwards at cycle " << k;
      prev = x;
      if (reached < 0 && std::abs(x - cs.to) <= 1e-12) reached = k;
    }
    ASSERT_GT(reached, 0) << cs.from << "->" << cs.to << " never reached";
    // Bang-bang minimum time plus the discrete braking curve's slack: the limiter
    // approaches along v = √(2·a·gap) sampled at dt, a few cycles slower than ideal.
    EXPECT_GE(reached * kDt, t_min - kDt) << cs.from << "->" << cs.to;
    EXPECT_LE(reached * kDt, 1.2 * t_min + 5 * kDt) << cs.from << "->" << cs.to;
    EXPECT_EQ(c.x(), cs.to);
    EXPECT_EQ(c.limiter().setpoint_velocity_mm_s(), 0.0);
    EXPECT_EQ(c.limiter().faults(), 0u);
  }
}

// A slow ramp target well inside the limits, passed with its velocity: once caught up
// the setpoint of cycle k is the target of cycle k ("land on the target this period if
// possible"; closing the gap already moves with the target, so its velocity must not
// be added a second time, which would make the setpoint lead by v·dt).
TEST(CommandLimiterTest, MovingTargetInsideLimitsIsTrackedExactly) {
  CheckedLimiter c;
  c.Reset(0.0);
  const double v = 20.0;
  double worst = 0.0;
  for (int k = 1; k <= 500; ++k) {
    const double target = v * k * kDt;
    const double x = c.Step(target, v);
    if (k > 50) {
      worst = std::max(worst, std::abs(x - target));
      ASSERT_NEAR(c.v(), v, 1e-6) << "cycle " << k;
    }
  }
  EXPECT_LE(worst, 1e-9) << "the setpoint is off a " << v << " mm/s target by " << worst << " mm";
  EXPECT_EQ(c.limiter().count(LimitEvent::kVelocity), 0u);
  EXPECT_EQ(c.limiter().faults(), 0u);
}

// A ramp target that stops between two samples: the setpoint arrives at the final
// position without passing it (the "reach a target without overshoot" promise, for a
// moving target).
TEST(CommandLimiterTest, RampTargetThatStopsIsNotOvershot) {
  CheckedLimiter c;
  c.Reset(0.0);
  const double v = 20.0, stop_at = 2.005;
  double peak = 0.0;
  for (int k = 1; k <= 300; ++k) {
    const double target = std::min(v * k * kDt, stop_at);
    const double x = c.Step(target, target < stop_at ? v : 0.0);
    peak = std::max(peak, x);
  }
  EXPECT_LE(peak, stop_at + 1e-12) << "overshoot " << peak - stop_at << " mm";
  EXPECT_NEAR(c.x(), stop_at, 1e-12);
  EXPECT_EQ(c.v(), 0.0);
}

TEST(CommandLimiterTest, ForceIsClampedAndNonFiniteForceIsZeroed) {
  Limits limits;
  limits.max_force_n = 26.7;
  CommandLimiter l(limits, kDt);
  EXPECT_EQ(l.Force(10.0), 10.0);
  EXPECT_EQ(l.Force(-26.7), -26.7);
  EXPECT_EQ(l.count(LimitEvent::kForce), 0u);
  EXPECT_EQ(l.Force(100.0), 26.7);
  EXPECT_EQ(l.Force(-1e300), -26.7);
  EXPECT_EQ(l.count(LimitEvent::kForce), 2u);
  EXPECT_EQ(l.Force(kNaN), 0.0);
  EXPECT_EQ(l.Force(kInf), 0.0);
  EXPECT_EQ(l.Force(-kInf), 0.0);
  EXPECT_EQ(l.count(LimitEvent::kNonFinite), 3u);
  EXPECT_EQ(l.count(LimitEvent::kForce), 2u);
  EXPECT_EQ(l.faults(), 5u);

  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> any(-1e9, 1e9);
  for (int k = 0; k < 10000; ++k) {
    const double f = l.Force(any(rng));
    ASSERT_LE(std::abs(f), 26.7);
  }
}

TEST(CommandLimiterTest, EventNames) {
  EXPECT_EQ(ToString(LimitEvent::kTravel), "travel");
  EXPECT_EQ(ToString(LimitEvent::kNonFinite), "non_finite");
  EXPECT_EQ(ToString(LimitEvent::kVelocity), "velocity");
  EXPECT_EQ(ToString(LimitEvent::kAcceleration), "acceleration");
  EXPECT_EQ(ToString(LimitEvent::kForce), "force");
}

void ExpectInvalidLimits(const Limits& limits, const std::string& field) {
  try {
    limits.Validate();
    ADD_FAILURE() << "accepted invalid " << field;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
  EXPECT_THROW(CommandLimiter(limits, kDt), std::invalid_argument) << field;
}

TEST(CommandLimiterTest, ValidateNamesTheField) {
  EXPECT_NO_THROW(Limits{}.Validate());
  for (double bad : {kNaN, kInf, -kInf}) {
    Limits l;
    l.travel_min_mm = bad;
    ExpectInvalidLimits(l, "travel_min_mm");
    l = Limits{};
    l.travel_max_mm = bad;
    ExpectInvalidLimits(l, "travel_max_mm");
  }
  Limits l;
  l.travel_min_mm = 5.0;
  l.travel_max_mm = 5.0;
  ExpectInvalidLimits(l, "travel_max_mm");
  l.travel_min_mm = 6.0;
  ExpectInvalidLimits(l, "travel_min_mm");
  for (double bad : {0.0, -1.0, kNaN, kInf}) {
    l = Limits{};
    l.max_velocity_mm_s = bad;
    ExpectInvalidLimits(l, "max_velocity_mm_s");
    l = Limits{};
    l.max_acceleration_mm_s2 = bad;
    ExpectInvalidLimits(l, "max_acceleration_mm_s2");
    l = Limits{};
    l.max_force_n = bad;
    ExpectInvalidLimits(l, "max_force_n");
  }
}

TEST(CommandLimiterTest, RejectsInvalidPeriod) {
  EXPECT_THROW(CommandLimiter(Limits{}, 0.0), std::invalid_argument);
  EXPECT_THROW(CommandLimiter(Limits{}, -1e-3), std::invalid_argument);
  EXPECT_THROW(CommandLimiter(Limits{}, kNaN), std::invalid_argument);
}

}  // namespace
}  // namespace echoservo::control
