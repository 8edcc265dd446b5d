// DelayLine: a fixed-rate ring buffer read back with linear interpolation.
#include "hw/delay_line.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace echoservo::hw {
namespace {

constexpr double kPeriod = 1e-3;
// Reading back a stored double involves at most a few roundings of delay/period.
constexpr double kTol = 1e-9;

// Pushes 1, 2, ..., n: the sample k steps before the newest then holds n - k.
DelayLine Ramp(int n, double max_delay_s) {
  DelayLine line(kPeriod, max_delay_s);
  for (int i = 1; i <= n; ++i) line.Push(static_cast<double>(i));
  return line;
}

TEST(DelayLine, ExactAtIntegerSteps) {
  const DelayLine line = Ramp(50, 0.02);
  for (int k = 0; k <= 20; ++k) {
    EXPECT_NEAR(line.Delayed(k * kPeriod), 50.0 - k, kTol) << "k=" << k;
  }
}

TEST(DelayLine, ExactAtIntegerStepsWithNonLinearSignal) {
  // Values that interpolation could not reproduce by accident.
  DelayLine line(kPeriod, 0.01);
  for (int i = 0; i < 40; ++i) line.Push(static_cast<double>(i * i) * 0.5 - 3.0 * (i % 3));
  for (int k = 0; k <= 10; ++k) {
    const int i = 39 - k;
    EXPECT_NEAR(line.Delayed(k * kPeriod), static_cast<double>(i * i) * 0.5 - 3.0 * (i % 3), kTol)
        << "k=" << k;
  }
}

TEST(DelayLine, LinearInterpolationBetweenSamples) {
  DelayLine line(kPeriod, 0.01);
  for (int i = 0; i < 30; ++i) line.Push(static_cast<double>(i * i));
  // Between the samples k and k+1 steps back the value is the straight line between them.
  for (int k = 0; k < 10; ++k) {
    const double a = static_cast<double>((29 - k) * (29 - k));
    const double b = static_cast<double>((28 - k) * (28 - k));
    for (double frac : {0.25, 0.5, 0.8}) {
      EXPECT_NEAR(line.Delayed((k + frac) * kPeriod), a + frac * (b - a), 1e-6 * std::abs(a))
          << "k=" << k << " frac=" << frac;
    }
  }
}

TEST(DelayLine, ClampsToMaxDelayAndToZero) {
  const double max_delay = 0.01;  // exactly 10 periods
  const DelayLine line = Ramp(100, max_delay);
  const double at_max = line.Delayed(max_delay);
  EXPECT_NEAR(at_max, 90.0, kTol);
  EXPECT_NEAR(line.Delayed(2.0 * max_delay), at_max, kTol);
  EXPECT_NEAR(line.Delayed(1.0), at_max, kTol);
  EXPECT_NEAR(line.Delayed(-0.005), 100.0, kTol);  // negative delay: the newest sample
}

TEST(DelayLine, ZeroMaxDelayReturnsNewest) {
  DelayLine line(kPeriod, 0.0);
  line.Push(3.0);
  line.Push(7.0);
  EXPECT_DOUBLE_EQ(line.Delayed(0.0), 7.0);
  EXPECT_DOUBLE_EQ(line.Delayed(0.5), 7.0);
}

TEST(DelayLine, StartsAtZeroAndResetFills) {
  DelayLine line(kPeriod, 0.005);
  EXPECT_DOUBLE_EQ(line.Delayed(0.003), 0.0);
  line.Push(1.0);
  line.Reset(-4.5);
  for (double d : {0.0, 0.0015, 0.005}) EXPECT_DOUBLE_EQ(line.Delayed(d), -4.5) << d;
  line.Push(5.5);  // one step of history: half a period back is the midpoint
  EXPECT_NEAR(line.Delayed(0.5 * kPeriod), 0.5, kTol);
  EXPECT_NEAR(line.Delayed(kPeriod), -4.5, kTol);
}

TEST(DelayLine, WrapsAroundTheRing) {
  // Many more pushes than the ring holds: still the newest samples are returned.
  DelayLine line(0.5, 2.0);
  for (int i = 0; i < 1003; ++i) line.Push(static_cast<double>(i));
  EXPECT_NEAR(line.Delayed(0.0), 1002.0, kTol);
  EXPECT_NEAR(line.Delayed(0.75), 1000.5, kTol);
  EXPECT_NEAR(line.Delayed(2.0), 998.0, kTol);
}

TEST(DelayLine, ConstructorValidation) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (double period : {0.0, -1e-3, nan}) {
    EXPECT_THROW(DelayLine(period, 0.01), std::invalid_argument) << period;
  }
  for (double max_delay : {-1e-3, nan, inf}) {
    EXPECT_THROW(DelayLine(kPeriod, max_delay), std::invalid_argument) << max_delay;
  }
  EXPECT_NO_THROW(DelayLine(kPeriod, 0.0));
}

}  // namespace
}  // namespace echoservo::hw
