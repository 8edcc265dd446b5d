// The slow-trend test behind the heartbeat EKF's automatic respiration term: it recovers
// a known cubic trend under a heartbeat at a wandering phase, and tells a trend from
// none under 0.3 mm noise.
#include "estimation/slow_trend.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "tests/test_util/expect_error.h"

namespace echoservo::estimation {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

constexpr double kWindowS = 4.0;

// 4 s at 25 vol/s of a two-harmonic beat at a phase that wanders around 72 bpm, plus
// trend(t) and white noise σ.
SlowTrendWindow Window(double (*trend)(double), double noise_mm) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> gauss(0.0, noise_mm);
  SlowTrendWindow w;
  w.Reset(2, kWindowS);
  for (int i = 0; i <= 100; ++i) {
    const double t = i / 25.0;
    const double theta = 2.0 * std::numbers::pi * 1.2 * t + 0.3 * std::sin(1.3 * t);
    const double z = 3.0 * std::cos(theta) + std::sin(2.0 * theta) + trend(t);
    w.Add(t, theta, z + (noise_mm > 0.0 ? gauss(rng) : 0.0));
  }
  return w;
}

double Cubic(double t) { return 0.5 * t * t - 0.1 * t * t * t; }  // mm
double None(double) { return 0.0; }

TEST(SlowTrend, RecoversAKnownCubicUnderAWanderingHeartbeat) {
  const TrendEvidence e = Window(Cubic, 0.0).Evidence();
  EXPECT_EQ(e.samples, 101u);
  EXPECT_DOUBLE_EQ(e.window_s, kWindowS);
  // The trend's second derivative 1 − 0.6t, RMS over the samples; its slope at 4 s.
  double ss = 0.0;
  for (int i = 0; i <= 100; ++i) ss += std::pow(1.0 - 0.6 * i / 25.0, 2);
  EXPECT_NEAR(e.accel_rms_mm_s2, std::sqrt(ss / 101.0), 1e-6);
  EXPECT_NEAR(e.drift_mm_s, kWindowS - 0.3 * kWindowS * kWindowS, 1e-6);
  EXPECT_TRUE(e.Significant());
}

TEST(SlowTrend, TellsATrendFromNoneUnderNoise) {
  EXPECT_TRUE(Window(Cubic, 0.3).Evidence().Significant());
  const TrendEvidence flat = Window(None, 0.3).Evidence();
  EXPECT_FALSE(flat.Significant());
  // The fitted curvature of pure noise is small beside the cubic's (≈ 1.2 mm/s²).
  EXPECT_LT(flat.accel_rms_mm_s2, 0.5);
}

TEST(SlowTrend, TooFewSamplesAreNoEvidenceAndBadWindowsAreErrors) {
  SlowTrendWindow w;
  w.Reset(12, kWindowS);  // 28 parameters: 56 samples needed
  for (int i = 0; i < 40; ++i) w.Add(i / 25.0, 0.5 * i, Cubic(i / 25.0));
  EXPECT_EQ(w.Evidence().parameters, 0);
  EXPECT_FALSE(w.Evidence().Significant());
  ExpectContains(InvalidArgumentMessage([&] { w.Reset(13, kWindowS); }), "harmonics");
  ExpectContains(InvalidArgumentMessage([&] { w.Reset(2, 0.0); }), "window");
}

}  // namespace
}  // namespace echoservo::estimation
