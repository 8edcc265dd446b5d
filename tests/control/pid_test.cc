// The discrete PID position controller: each term on its own, saturation, anti-windup
// and gain validation. The expected values follow from the control law in
// control/pid.h (u = kp·e + ki·Σe·dt − kd·ẏ_filtered, saturated at ±limit); they are
// exact up to a few ulps, hence the 1e-12 relative tolerances.
#include "control/pid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "tests/test_util/constants.h"

namespace echoservo::control {
namespace {

using testing::kDt;

PidGains Gains(double kp, double ki, double kd, double limit = 26.7) {
  PidGains g;
  g.kp_n_per_mm = kp;
  g.ki_n_per_mm_s = ki;
  g.kd_n_per_mm_per_s = kd;
  g.output_limit_n = limit;
  return g;
}

TEST(PidTest, ProportionalOnlyOutputIsKpTimesError) {
  Pid pid(Gains(12.0, 0.0, 0.0), kDt);
  for (double e : {0.0, 0.5, -1.25, 2.0, -0.01}) {
    const double measurement = 3.0;
    EXPECT_NEAR(pid.Update(measurement + e, measurement), 12.0 * e, 1e-12) << "e=" << e;
    EXPECT_FALSE(pid.saturated());
  }
}

TEST(PidTest, FeedforwardIsAddedBeforeSaturation) {
  Pid pid(Gains(2.0, 0.0, 0.0, 10.0), kDt);
  EXPECT_NEAR(pid.Update(1.0, 0.0, 3.0), 2.0 + 3.0, 1e-12);
  EXPECT_EQ(pid.Update(1.0, 0.0, 20.0), 10.0);
  EXPECT_TRUE(pid.saturated());
}

TEST(PidTest, IntegralAccumulatesKiTimesErrorTimesDt) {
  const double ki = 150.0;
  Pid pid(Gains(0.0, ki, 0.0), kDt);
  pid.Reset(0.0);
  const double e = 0.02;  // small enough to stay below the limit for 100 cycles
  for (int n = 1; n <= 100; ++n) {
    const double u = pid.Update(e, 0.0);
    EXPECT_NEAR(u, n * ki * e * kDt, 1e-12 * n) << "cycle " << n;
    EXPECT_NEAR(pid.integral(), n * ki * e * kDt, 1e-12 * n);
  }
  // A negative error integrates back down at the same rate.
  for (int n = 1; n <= 40; ++n) pid.Update(-e, 0.0);
  EXPECT_NEAR(pid.integral(), 60 * ki * e * kDt, 1e-10);
}

TEST(PidTest, ResetClearsTheIntegral) {
  Pid pid(Gains(0.0, 100.0, 0.0), kDt);
  for (int n = 0; n < 50; ++n) pid.Update(0.1, 0.0);
  EXPECT_GT(pid.integral(), 0.0);
  pid.Reset(0.0);
  EXPECT_EQ(pid.integral(), 0.0);
  EXPECT_EQ(pid.Update(0.0, 0.0), 0.0);
}

// Derivative on the measurement: a setpoint step moves the proportional term only.
TEST(PidTest, SetpointStepDoesNotKickTheDerivative) {
  Pid d_only(Gains(0.0, 0.0, 0.07), kDt);
  d_only.Reset(1.0);
  EXPECT_EQ(d_only.Update(1.0, 1.0), 0.0);
  EXPECT_EQ(d_only.Update(6.0, 1.0), 0.0);  // 5 mm setpoint step, measurement still
  EXPECT_EQ(d_only.Update(-4.0, 1.0), 0.0);

  // With P: the step gives exactly kp·e; a derivative on the error would add
  // kd·α·(5 mm / 1 ms) ≈ 300 N and saturate the output.
  Pid pd(Gains(2.0, 0.0, 0.07), kDt);
  pd.Reset(0.0);
  EXPECT_EQ(pd.Update(0.0, 0.0), 0.0);
  EXPECT_NEAR(pd.Update(5.0, 0.0), 2.0 * 5.0, 1e-12);
  EXPECT_FALSE(pd.saturated());
}

// A measurement ramp at v mm/s: the first-order filter (α = 1 − exp(−2π·fc·dt)) gives
// ẏ_n = v·(1 − (1 − α)^n), and the output is −kd·ẏ_n.
TEST(PidTest, DerivativeActsOnFilteredMeasurementRate) {
  PidGains g = Gains(0.0, 0.0, 0.07);
  g.derivative_cutoff_hz = 100.0;
  Pid pid(g, kDt);
  pid.Reset(0.0);
  const double v = 20.0;  // mm/s
  const double alpha = 1.0 - std::exp(-2.0 * std::numbers::pi * 100.0 * kDt);
  for (int n = 1; n <= 60; ++n) {
    const double y = v * n * kDt;
    const double u = pid.Update(y, y);  // zero error: only the derivative acts
    const double expected = -0.07 * v * (1.0 - std::pow(1.0 - alpha, n));
    ASSERT_NEAR(u, expected, 1e-9 * 0.07 * v) << "cycle " << n;
  }
}

TEST(PidTest, OutputSaturatesAtTheLimit) {
  const double limit = 26.7;
  Pid pid(Gains(12.0, 150.0, 0.07, limit), kDt);
  pid.Reset(0.0);
  EXPECT_EQ(pid.Update(1000.0, 0.0), limit);
  EXPECT_TRUE(pid.saturated());
  pid.Reset(0.0);
  EXPECT_EQ(pid.Update(-1000.0, 0.0), -limit);
  EXPECT_TRUE(pid.saturated());
  pid.Reset(0.0);
  EXPECT_EQ(pid.Update(0.0, 0.0, 1e6), limit);
  EXPECT_EQ(pid.Update(0.0, 0.0, -1e6), -limit);
  // Whatever the inputs, |u| ≤ limit.
  for (int n = 0; n < 2000; ++n) {
    const double sp = 50.0 * std::sin(0.37 * n) * std::cos(0.011 * n);
    const double y = 30.0 * std::sin(0.05 * n);
    const double u = pid.Update(sp, y, 10.0 * std::cos(0.2 * n));
    ASSERT_LE(std::abs(u), limit) << "cycle " << n;
    ASSERT_LE(std::abs(pid.integral()), limit) << "cycle " << n;
  }
}

// A textbook PID with an unbounded integrator, for comparison.
struct NaivePid {
  double kp, ki, limit, integral = 0.0;
  double Update(double e) {
    integral += ki * e * kDt;
    return std::clamp(kp * e + integral, -limit, limit);
  }
};

// Long saturation in one direction, then the error reverses. With the integral bounded
// by ±limit and frozen while saturated, the output drops below the limit on the first
// reversed cycle (u ≤ limit − kp·|e_r|) and crosses zero within
// (limit − kp·|e_r|)/(ki·|e_r|·dt) cycles, whereas a naive integrator that wound up to
// ki·e₁·T must first unwind all of it.
TEST(PidTest, AntiWindupLeavesSaturationPromptlyWhenTheErrorReverses) {
  const double kp = 12.0, ki = 150.0, limit = 26.7;
  for (double e1 : {0.5, 1.0, 3.0, 20.0}) {
    Pid pid(Gains(kp, ki, 0.0, limit), kDt);
    NaivePid naive{kp, ki, limit};
    pid.Reset(0.0);
    const int hold = 5000;  // 5 s pushing one way
    double u = 0.0;
    for (int n = 0; n < hold; ++n) {
      u = pid.Update(e1, 0.0);
      naive.Update(e1);
    }
    // At (or within one integration step of) the positive limit.
    ASSERT_GE(u, limit - ki * e1 * kDt - 1e-9) << "e1=" << e1;
    ASSERT_LE(pid.integral(), limit);

    const double er = 1.0;  // reversed error magnitude
    const int bound = static_cast<int>(std::ceil((limit - kp * er) / (ki * er * kDt)));
    int naive_cycles = 0;
    while (naive.Update(-er) > 0.0) ++naive_cycles;
    const double first = pid.Update(-er, 0.0);
    EXPECT_LE(first, limit - kp * er + 1e-9) << "e1=" << e1 << ": did not leave saturation at once";
    EXPECT_FALSE(pid.saturated() && first > 0.0);
    int cycles = 1;
    for (double v = first; v > 0.0; v = pid.Update(-er, 0.0)) {
      ++cycles;
      ASSERT_LE(cycles, bound + 1) << "e1=" << e1 << ": output still positive";
    }
    // The bound itself is far below the naive integrator's unwinding time.
    EXPECT_LT(10 * bound, naive_cycles) << "e1=" << e1;
  }
}

TEST(PidTest, IntegralIsBoundedByTheOutputLimitUnderPureIntegralAction) {
  Pid pid(Gains(0.0, 150.0, 0.0, 5.0), kDt);
  pid.Reset(0.0);
  for (int n = 0; n < 10000; ++n) {
    const double u = pid.Update(10.0, 0.0);
    ASSERT_LE(u, 5.0);
    ASSERT_LE(pid.integral(), 5.0);
  }
  EXPECT_NEAR(pid.Update(10.0, 0.0), 5.0, 1.5);  // stays near the limit
}

// Expects PidGains::Validate to throw std::invalid_argument naming `field`.
void ExpectInvalidGain(const PidGains& g, const std::string& field) {
  try {
    g.Validate();
    ADD_FAILURE() << "accepted invalid " << field;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
  EXPECT_THROW(Pid(g, kDt), std::invalid_argument) << field;
}

TEST(PidTest, GainValidationNamesTheGain) {
  EXPECT_NO_THROW(PidGains{}.Validate());
  EXPECT_NO_THROW(Gains(0.0, 0.0, 0.0).Validate());  // zero gains are allowed
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (double bad : {-1.0, nan, inf}) {
    PidGains g;
    g.kp_n_per_mm = bad;
    ExpectInvalidGain(g, "kp_n_per_mm");
    g = PidGains{};
    g.ki_n_per_mm_s = bad;
    ExpectInvalidGain(g, "ki_n_per_mm_s");
    g = PidGains{};
    g.kd_n_per_mm_per_s = bad;
    ExpectInvalidGain(g, "kd_n_per_mm_per_s");
    g = PidGains{};
    g.derivative_cutoff_hz = bad;
    ExpectInvalidGain(g, "derivative_cutoff_hz");
    g = PidGains{};
    g.output_limit_n = bad;
    ExpectInvalidGain(g, "output_limit_n");
  }
  PidGains g;
  g.derivative_cutoff_hz = 0.0;
  ExpectInvalidGain(g, "derivative_cutoff_hz");
  g = PidGains{};
  g.output_limit_n = 0.0;
  ExpectInvalidGain(g, "output_limit_n");
}

TEST(PidTest, RejectsInvalidPeriod) {
  EXPECT_THROW(Pid(PidGains{}, 0.0), std::invalid_argument);
  EXPECT_THROW(Pid(PidGains{}, -1e-3), std::invalid_argument);
  EXPECT_THROW(Pid(PidGains{}, std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
}

}  // namespace
}  // namespace echoservo::control
