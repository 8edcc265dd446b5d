// The heartbeat significance test (estimation/heartbeat_significance.h): no heartbeat on
// detection noise (false-alarm rate within the stated probability), a random walk or a slow
// drift; a real heartbeat found within about two beats.
#include "estimation/heartbeat_significance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "control/experiments/synthetic_motion.h"
#include "estimation/fourier_motion.h"

namespace echoservo::estimation {
namespace {

constexpr double kVolumeRateHz = 25.0;  // the live pipeline's volume rate

#ifdef ECHOSERVO_SANITIZED
constexpr int kScale = 4;  // fewer trials under the sanitizers' slower build
#else
constexpr int kScale = 1;
#endif

// The one-sided upper bound of a binomial count's rate: p + 4σ (false alarms beyond it
// have probability < 1e-4 under the stated p).
double UpperRate(double p, int trials) { return p + 4.0 * std::sqrt(p * (1.0 - p) / trials); }

TEST(FisherF, SurvivalMatchesKnownQuantiles) {
  // F(2, d2): P(F > f) = (1 + 2f/d2)^(−d2/2) exactly.
  for (double f : {0.5, 2.0, 7.0}) {
    EXPECT_NEAR(FisherFSurvival(f, 2.0, 40.0), std::pow(1.0 + 2.0 * f / 40.0, -20.0), 1e-12);
  }
  // Tables: F(6, 90) 0.99 quantile 3.0, F(1, 10) 0.95 quantile 4.965.
  EXPECT_NEAR(FisherFSurvival(4.965, 1.0, 10.0), 0.05, 5e-4);
  EXPECT_NEAR(FisherFSurvival(3.0, 6.0, 90.0), 0.0100, 1e-3);
  EXPECT_EQ(FisherFSurvival(0.0, 3.0, 7.0), 1.0);
}

TEST(HeartbeatSignificance, RejectsBadOptionsAndInput) {
  HeartbeatSignificanceOptions o;
  o.window_s = 2.0;  // one beat at 0.5 Hz
  EXPECT_THROW(HeartbeatSignificance{o}, std::invalid_argument);
  o = {};
  o.false_alarm = 0.0;
  EXPECT_THROW(HeartbeatSignificance{o}, std::invalid_argument);
  HeartbeatSignificance s;
  s.Add(1.0, 0.0);
  EXPECT_THROW(s.Add(1.0, 0.0), std::invalid_argument);
  EXPECT_THROW(s.Add(2.0, NAN), std::invalid_argument);
  EXPECT_FALSE(s.Evaluate().significant);
}

// Detection noise alone, in independent 4 s windows: the F-test's false-alarm rate is at
// most the stated probability (Bonferroni is conservative), and the whole test's is lower.
TEST(HeartbeatSignificance, FalseAlarmRateOnDetectionNoiseWithinTheStatedProbability) {
  HeartbeatSignificanceOptions o;
  o.false_alarm = 0.02;  // large enough to count false alarms in a few hundred windows
  const int windows = 1200 / kScale;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.05);  // mm: the static scene's detections
  int f_alarms = 0;
  int alarms = 0;
  for (int w = 0; w < windows; ++w) {
    HeartbeatSignificance s(o);
    for (int i = 0; i <= 100; ++i) s.Add(i / kVolumeRateHz, 20.0 + noise(rng));
    const HeartbeatEvidence& e = s.Evaluate();
    f_alarms += e.p_value < o.false_alarm;
    alarms += e.significant;
  }
  const double f_rate = static_cast<double>(f_alarms) / windows;
  std::printf("F-test false-alarm rate %.4f (stated %.3f), whole test %.4f over %d windows\n",
              f_rate, o.false_alarm, static_cast<double>(alarms) / windows, windows);
  EXPECT_LE(f_rate, UpperRate(o.false_alarm, windows));
  EXPECT_LE(alarms, f_alarms);
}

// A long static run at the default 1e-3: never significant.
TEST(HeartbeatSignificance, StaticTargetNeverSignificantOverALongRun) {
  HeartbeatSignificance s;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 0.05);
  std::student_t_distribution<double> heavy(2.0);  // and heavy-tailed outliers
  const int n = static_cast<int>(120.0 * kVolumeRateHz) / kScale;
  int evaluated = 0;
  int significant = 0;
  double max_snr_ratio = 0.0;
  for (int i = 0; i < n; ++i) {
    const double z = 64.0 + noise(rng) + (i % 37 == 0 ? 0.5 * heavy(rng) : 0.0);
    s.Add(i / kVolumeRateHz, z);
    if (i % 5 != 0) continue;  // every 0.2 s: the windows overlap 96 % anyway
    const HeartbeatEvidence& e = s.Evaluate();
    if (e.snr_threshold > 0.0) {
      ++evaluated;
      max_snr_ratio = std::max(max_snr_ratio, e.peak_snr / e.snr_threshold);
    }
    significant += e.significant;
  }
  std::printf("static: %d of %d evaluations significant; max peak SNR / threshold %.2f\n",
              significant, evaluated, max_snr_ratio);
  EXPECT_GT(evaluated, n / 10);
  // ≤ 1e-3 per (correlated) evaluation: < 1 expected; the repetition and amplitude
  // conditions remove those the F-test lets through.
  EXPECT_EQ(significant, 0);
  EXPECT_FALSE(s.evidence().significant);
  EXPECT_NE(s.evidence().reason.find("no significant heartbeat"), std::string::npos);
}

// A random walk (the detection drifting) plus noise does not repeat: not significant (the
// F-test alone fires on most: a random walk's spectrum is red, not white).
TEST(HeartbeatSignificance, RandomWalkIsNotSignificant) {
  const int walks = 400 / kScale;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> unit(0.0, 1.0);
  int alarms = 0;
  int f_alarms = 0;
  for (int w = 0; w < walks; ++w) {
    HeartbeatSignificance s;
    double x = 0.0;
    const double step_mm = 0.05 + 0.3 * (w % 7) / 6.0;  // 0.05–0.35 mm per volume
    for (int i = 0; i <= 150; ++i) {                    // 6 s: the window (5 s) full
      x += step_mm * unit(rng);
      s.Add(i / kVolumeRateHz, x + 0.05 * unit(rng));
    }
    const HeartbeatEvidence& e = s.Evaluate();
    alarms += e.significant;
    f_alarms += e.p_value < s.options().false_alarm;
  }
  std::printf("random walk: F-test alone %d of %d, whole test %d\n", f_alarms, walks, alarms);
  EXPECT_LE(static_cast<double>(alarms) / walks, 0.01);
}

TEST(HeartbeatSignificance, SlowDriftIsNotSignificant) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.1);
  HeartbeatSignificance s;
  int significant = 0;
  // Drift 2 mm/s and a 0.2 Hz, 4 mm breathing-like sway (below the heart-rate band).
  for (int i = 0; i < static_cast<int>(60.0 * kVolumeRateHz) / kScale; ++i) {
    const double t = i / kVolumeRateHz;
    s.Add(t, 2.0 * t + 2.0 * std::sin(kTwoPi * 0.2 * t) + noise(rng));
    if (i % 5 == 0) significant += s.Evaluate().significant;
  }
  EXPECT_EQ(significant, 0) << s.evidence().reason;
}

// A heartbeat of 60–120 bpm, 2–5 mm peak to peak (the mitral shape with heart-rate
// variability), 0.3 mm detection noise at 25 vol/s: significant within three beats, and
// stays so.
TEST(HeartbeatSignificance, RealHeartbeatSignificantWithinThreeBeats) {
  double worst_beats = 0.0;
#ifdef ECHOSERVO_SANITIZED
  const std::vector<double> rates_bpm{60.0, 120.0};
#else
  const std::vector<double> rates_bpm{60.0, 80.0, 100.0, 120.0};
#endif
  for (double bpm : rates_bpm) {
    for (double p2p : {2.0, 5.0}) {
      control::SyntheticMotionOptions mo = control::MitralHrvDefaults();
      mo.heart_rate_bpm = bpm;
      mo.peak_to_peak_mm = p2p;
      mo.duration_s = 8.0;
      mo.sample_rate_hz = kVolumeRateHz;
      mo.seed = static_cast<std::uint64_t>(bpm + p2p);
      const control::SyntheticMotion m = control::MakeSyntheticMotion(mo);
      HeartbeatSignificance s;
      double first_s = -1.0;
      int after = 0;
      int lost = 0;
      const double t0 = m.measured.t_s.front();
      for (std::size_t i = 0; i < m.measured.t_s.size(); ++i) {
        s.Add(m.measured.t_s[i], m.measured.position_mm[i]);
        const HeartbeatEvidence& e = s.Evaluate();
        if (first_s < 0.0 && e.significant) first_s = m.measured.t_s[i] - t0;
        if (first_s >= 0.0) {
          ++after;
          lost += !e.significant;
        }
      }
      ASSERT_GE(first_s, 0.0) << bpm << " bpm " << p2p << " mm: " << s.evidence().reason;
      const double beats = first_s * bpm / 60.0;
      worst_beats = std::max(worst_beats, beats);
      std::printf(
          "%.0f bpm, %.0f mm: significant after %.2f s (%.2f beats), lost %d of %d, "
          "rate %.2f Hz, SNR %.1f\n",
          bpm, p2p, first_s, beats, lost, after, s.evidence().rate_hz, s.evidence().peak_snr);
      EXPECT_LE(beats, 3.0) << bpm << " bpm " << p2p << " mm";
      EXPECT_EQ(lost, 0) << bpm << " bpm " << p2p << " mm";
      EXPECT_NEAR(s.evidence().rate_hz, bpm / 60.0, 0.15 * bpm / 60.0);
      EXPECT_GT(s.evidence().confidence(), 0.99);
    }
  }
  std::printf("worst time to significance: %.2f beats\n", worst_beats);
}

}  // namespace
}  // namespace echoservo::estimation
