// The realistic heart-trace generator (estimation/realistic_heart_trace.h): deterministic
// per seed; its irregularities are there and measurable from outside (heavy-tailed noise,
// dropped samples, the rate step, ectopic beats' timing), and bad options are rejected.
#include "estimation/realistic_heart_trace.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "tests/test_util/expect_error.h"

namespace echoservo::estimation {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

// The dominant period (s) of the truth over [from, to): the first autocorrelation peak
// above half the variance, over lags 0.25–2 s.
double DominantPeriod(const MotionTrace& truth, double from, double to) {
  std::vector<double> z;
  for (std::size_t i = 0; i < truth.size(); ++i)
    if (truth.t_s[i] >= from && truth.t_s[i] < to) z.push_back(truth.position_mm[i]);
  double mean = 0.0;
  for (double v : z) mean += v / static_cast<double>(z.size());
  const double dt = truth.t_s[1] - truth.t_s[0];
  auto corr = [&](std::size_t lag) {
    double c = 0.0;
    for (std::size_t i = 0; i + lag < z.size(); ++i) c += (z[i] - mean) * (z[i + lag] - mean);
    return c / static_cast<double>(z.size() - lag);
  };
  const double c0 = corr(0);
  for (auto lag = static_cast<std::size_t>(0.25 / dt); lag <= static_cast<std::size_t>(2.0 / dt);
       ++lag) {
    const double c = corr(lag);
    if (c > 0.5 * c0 && c >= corr(lag - 1) && c >= corr(lag + 1))
      return static_cast<double>(lag) * dt;
  }
  return 0.0;
}

TEST(RealisticHeartTrace, IsDeterministicPerSeed) {
  const MotionTrace a = GenerateRealisticHeartTrace(RealisticHeartClass("noisy", 4));
  const MotionTrace b = GenerateRealisticHeartTrace(RealisticHeartClass("noisy", 4));
  const MotionTrace c = GenerateRealisticHeartTrace(RealisticHeartClass("noisy", 5));
  EXPECT_EQ(a.position_mm, b.position_mm);
  EXPECT_NE(a.position_mm, c.position_mm);
  ASSERT_NO_THROW(ValidateMotionTrace(a));
}

TEST(RealisticHeartTrace, HasHeavyTailsDropsAndARateStep) {
  RealisticHeartOptions o = RealisticHeartClass("rate_steps", 9);
  o.rate_drift_bpm_per_min = 0.0;
  o.hrv_bpm = 0.0;
  o.rsa_bpm = 0.0;
  o.breathing_mm = 0.0;
  o.outlier_probability = 0.0;
  o.burst_probability = 0.0;
  o.drop_probability = 0.1;
  o.duration_s = 40.0;
  o.rate_step_at_s = 20.0;
  MotionTrace truth;
  const MotionTrace m = GenerateRealisticHeartTrace(o, &truth);
  // Drops: 10 % of 1001 samples (binomial σ ≈ 9.5).
  const double dropped = static_cast<double>(truth.size() - m.size());
  EXPECT_NEAR(dropped, 100.0, 30.0);
  // Heavy tails: Student t₃ has infinite kurtosis; Gaussian noise would give 3 ± 0.3.
  std::vector<double> e;
  std::size_t j = 0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    while (truth.t_s[j] < m.t_s[i]) ++j;
    e.push_back(m.position_mm[i] - truth.position_mm[j]);
  }
  double m2 = 0.0, m4 = 0.0;
  for (double v : e) {
    m2 += v * v / static_cast<double>(e.size());
    m4 += v * v * v * v / static_cast<double>(e.size());
  }
  EXPECT_GT(m4 / (m2 * m2), 4.5);
  // The rate step 62 → 92 bpm: periods 0.968 s and 0.652 s, within a sample (0.04 s).
  EXPECT_NEAR(DominantPeriod(truth, 2.0, 19.0), 60.0 / 62.0, 0.04);
  EXPECT_NEAR(DominantPeriod(truth, 22.0, 40.0), 60.0 / 92.0, 0.04);
}

TEST(RealisticHeartTrace, EctopicBeatsKeepTheSinusTiming) {
  // Compensatory pauses: a premature beat and its pause span two normal RR intervals, so
  // the long-run period is unchanged (autocorrelation at 2 RR), while the beat-to-beat
  // pattern is irregular (the trace is not periodic at 1 RR as the regular one is).
  RealisticHeartOptions o = RealisticHeartClass("ectopic", 3);
  o.hrv_bpm = o.rsa_bpm = o.breathing_mm = o.noise_mm = 0.0;
  o.outlier_probability = o.drop_probability = o.burst_probability = 0.0;
  o.ectopic_probability = 0.3;
  RealisticHeartOptions regular = o;
  regular.ectopic_probability = 0.0;
  MotionTrace with, without;
  GenerateRealisticHeartTrace(o, &with);
  GenerateRealisticHeartTrace(regular, &without);
  auto repeat_error = [](const MotionTrace& t, double lag_s) {
    const auto lag = static_cast<std::size_t>(std::lround(lag_s * 25.0));
    double ss = 0.0, var = 0.0;
    for (std::size_t i = 0; i + lag < t.size(); ++i) {
      ss += std::pow(t.position_mm[i + lag] - t.position_mm[i], 2);
      var += t.position_mm[i] * t.position_mm[i];
    }
    return ss / var;
  };
  const double rr = 60.0 / o.heart_bpm;
  EXPECT_LT(repeat_error(without, rr), 0.05);  // the lag is rounded to a sample
  EXPECT_GT(repeat_error(with, rr), 0.2);
}

TEST(RealisticHeartTrace, RejectsBadOptionsAndUnknownClasses) {
  RealisticHeartOptions o;
  o.sample_rate_hz = 0.0;
  ExpectContains(InvalidArgumentMessage([&] { GenerateRealisticHeartTrace(o); }),
                 "realistic heart trace");
  ExpectContains(InvalidArgumentMessage([&] { RealisticHeartClass("nope"); }),
                 "unknown class 'nope' (known: regular, ectopic");
}

}  // namespace
}  // namespace echoservo::estimation
