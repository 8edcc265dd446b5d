// The heartbeat EKF at the issue's figures (synthetic mitral trace with heart-rate
// variability and 0.3 mm noise; the real phantom trace), its exported motion, rate
// tracking, gating, coasting, re-initialisation and bad input.
#include "estimation/heartbeat_ekf.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

#include "control/trajectory.h"
#include "estimation/prediction_eval.h"
#include "tests/estimation/predictor_test_util.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo::estimation {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;
using echoservo::testing::MitralHrvTrace;
using echoservo::testing::TruthOf;

PredictionRunOptions At25Hz() {
  PredictionRunOptions o;
  o.latency_s = 0.1;
  o.measurement_rate_hz = 25.0;
  return o;
}

TEST(HeartbeatEkf, MeetsTheIssueFigureOnTheMitralTraceWithHeartRateVariability) {
  const control::SyntheticMotion m = MitralHrvTrace();
  const PredictionRun noisy = RunPrediction(m.measured, At25Hz());
  // Against the noisy trace itself (its 0.3 mm noise is in every error).
  EXPECT_LE(noisy.ekf.rms_mm, 0.5);
  EXPECT_LE(noisy.ekf.rms_mm, noisy.baselines.front().rms_mm / 5.0);
  EXPECT_EQ(noisy.baselines.front().name, "zero_order_hold");
  // Against the noise-free truth the prediction error itself is smaller than the noise.
  const MotionTrace truth = TruthOf(m);
  PredictionRunOptions o = At25Hz();
  o.truth = &truth;
  const PredictionRun clean = RunPrediction(m.measured, o);
  EXPECT_LT(clean.ekf.rms_mm, 0.4);
  EXPECT_LT(clean.ekf.rms_mm, noisy.ekf.rms_mm);
  EXPECT_EQ(clean.initialisations, 1u);
  // The baselines are worse than the zero-order hold here (noise × 1/dt amplification).
  for (const PredictionScore& b : clean.baselines)
    EXPECT_GT(b.rms_mm, 5.0 * clean.ekf.rms_mm) << b.name;
}

// The figure on every realisation of the heart-rate variability, not on one: seeds 1–10
// (docs/predictor.md reports seeds 11–20, never used in development, as a held-out check).
TEST(HeartbeatEkf, MeetsTheIssueFigureOnEverySeed) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "a statistical figure over seeds; the EKF runs under the sanitizers in "
      "the other HeartbeatEkf cases");
  // The reference is the noisy trace, whose noise is in every error: 0.5 mm in all leaves
  // √(0.5² − σ²) for the prediction error itself, against the noise-free truth.
  const double noise_mm = control::MitralHrvDefaults().noise_mm;
  const double own_mm = std::sqrt(0.5 * 0.5 - noise_mm * noise_mm);
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    const control::SyntheticMotion m = MitralHrvTrace(0.0, seed);
    const PredictionRun noisy = RunPrediction(m.measured, At25Hz());
    EXPECT_LE(noisy.ekf.rms_mm, 0.5) << "seed " << seed;
    EXPECT_LE(5.0 * noisy.ekf.rms_mm, noisy.baselines.front().rms_mm) << "seed " << seed;
    EXPECT_FALSE(noisy.respiration) << "seed " << seed << ": this trace does not breathe";
    const MotionTrace truth = TruthOf(m);
    PredictionRunOptions o = At25Hz();
    o.truth = &truth;
    EXPECT_LE(RunPrediction(m.measured, o).ekf.rms_mm, own_mm) << "seed " << seed;
  }
}

// Seed 5's heart rate swings 68 → 78 → 71 bpm within the 4 s initialisation window: a
// fixed-rate fit blurs the higher harmonics there, the warm-started filters do not.
TEST(HeartbeatEkf, KeepsTheMitralHarmonicsWhenTheRateChangesDuringInitialisation) {
  const control::SyntheticMotion m = MitralHrvTrace(0.0, 5);
  const auto [slowest, fastest] =
      std::minmax_element(m.heart_rate_bpm.begin(), m.heart_rate_bpm.begin() + 1001);  // 4 s
  ASSERT_GT(*fastest - *slowest, 5.0);
  const PredictionRun r = RunPrediction(m.measured, At25Hz());
  // As many as a clean, steady mitral shape needs (ChoosesFewHarmonics… below).
  EXPECT_GE(r.harmonics, 5);
}

TEST(HeartbeatEkf, CarriesTheRespirationTermWhenTheTraceBreathes) {
  const control::SyntheticMotion m = MitralHrvTrace(2.5);  // 2.5 mm at 0.25 Hz
  const PredictionRun automatic = RunPrediction(m.measured, At25Hz());
  EXPECT_TRUE(automatic.respiration);
  EXPECT_EQ(automatic.initialisations, 1u);
  PredictionRunOptions o = At25Hz();
  o.ekf.respiration = Respiration::kOn;
  const PredictionRun on = RunPrediction(m.measured, o);
  EXPECT_DOUBLE_EQ(automatic.ekf.rms_mm, on.ekf.rms_mm);  // the same filter
  // Without the offset rate the offset's random walk lags breathing of up to 3.9 mm/s.
  o.ekf.respiration = Respiration::kOff;
  const PredictionRun off = RunPrediction(m.measured, o);
  EXPECT_LT(2.0 * automatic.ekf.rms_mm, off.ekf.rms_mm);
}

TEST(HeartbeatEkf, SwitchesTheRespirationTermOnWhenBreathingStartsLater) {
  const control::SyntheticMotion m = MitralHrvTrace();
  MotionTrace measured = ResampleTrace(m.measured, 25.0);
  const double start_s = 12.0;  // e.g. the ventilator starts: 2.5 mm at 0.25 Hz
  for (std::size_t i = 0; i < measured.size(); ++i) {
    const double t = measured.t_s[i] - start_s;
    if (t > 0.0) measured.position_mm[i] += 2.5 * std::sin(2.0 * std::numbers::pi * 0.25 * t);
  }
  HeartbeatEkf ekf;
  double switched_s = -1.0;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    ekf.Update(measured.t_s[i], measured.position_mm[i]);
    if (switched_s < 0.0 && ekf.respiration()) switched_s = measured.t_s[i];
  }
  EXPECT_EQ(ekf.initialisations(), 1u);
  // Two 4 s windows with the trend, after at most one that straddles the start.
  EXPECT_GT(switched_s, start_s);
  EXPECT_LE(switched_s, start_s + 3.0 * ekf.options().init_window_s);
  EXPECT_GT(ekf.offset_rate_q_mm_s(), 0.0);
}

TEST(HeartbeatEkf, IsThreeTimesBetterThanZeroOrderHoldOnThePhantom) {
  const MotionTrace phantom = ReadMotionTrace(echoservo::testing::PhantomPath(), "POI_z");
  PredictionRunOptions o;
  o.latency_s = 0.1;  // two samples at the assumed 20 Hz
  const PredictionRun r = RunPrediction(phantom, o);
  EXPECT_LE(3.0 * r.ekf.rms_mm, r.baselines.front().rms_mm);
  // The phantom beats at 16.79 samples per beat: 71.5 bpm at the assumed 20 Hz. The
  // filter's rate is free to wander (it follows heart-rate variability): within 3 %.
  EXPECT_NEAR(60.0 * r.rate_hz, 60.0 * 20.0 / 16.786, 2.0);
}

TEST(HeartbeatEkf, FollowsAHeartRateDriftAndKeepsPredicting) {
  control::SyntheticMotionOptions so = control::MitralHrvDefaults();
  so.rsa_bpm = 0.0;
  so.wander_bpm = 0.0;
  so.rate_drift_bpm_per_min = 30.0;  // 72 → 92 bpm over 40 s
  const control::SyntheticMotion m = control::MakeSyntheticMotion(so);
  const PredictionRun r = RunPrediction(m.measured, At25Hz());
  EXPECT_NEAR(60.0 * r.rate_hz, m.heart_rate_bpm.back(), 1.5);
  EXPECT_LE(r.ekf.rms_mm, r.baselines.front().rms_mm / 5.0);
}

TEST(HeartbeatEkf, ExportedMotionMatchesItsPredictionUntilTheHorizon) {
  const control::SyntheticMotion m = MitralHrvTrace();
  HeartbeatEkf ekf;
  for (std::size_t i = 0; i < m.measured.size() && m.measured.t_s[i] < 10.0; i += 10) {
    ekf.Update(m.measured.t_s[i], m.measured.position_mm[i]);
  }
  ASSERT_TRUE(ekf.initialised());
  const FourierMotion motion = ekf.Motion();
  EXPECT_EQ(motion.sin_mm.front(), 0.0);  // the phase-anchoring constraint
  EXPECT_DOUBLE_EQ(motion.valid_until_s, motion.t0_s + ekf.options().horizon_s);
  EXPECT_NEAR(motion.frequency_hz, ekf.rate_hz(), 1e-12);
  for (double dt = 0.0; dt <= 0.3; dt += 0.001) {
    EXPECT_NEAR(motion.Position(motion.t0_s + dt), ekf.Predict(motion.t0_s + dt), 1e-9);
  }
  EXPECT_TRUE(motion.ValidAt(motion.t0_s + 0.1));
  EXPECT_FALSE(motion.ValidAt(motion.t0_s + 0.6));
}

TEST(HeartbeatEkf, ChoosesFewHarmonicsForASineAndManyForTheMitralShape) {
  auto chosen = [](auto shape) {
    HeartbeatEkf ekf;
    for (int i = 0; i <= 125; ++i) {
      const double t = i / 25.0;
      ekf.Update(t, shape(t));
    }
    return ekf.harmonics();
  };
  EXPECT_LE(chosen([](double t) { return 5.0 * std::cos(2.0 * std::numbers::pi * 1.2 * t); }), 2);
  const control::MitralTrajectory mitral;
  EXPECT_GE(chosen([&](double t) { return mitral.Evaluate(t).position_mm; }), 5);
}

TEST(HeartbeatEkf, RejectsOutliersByInnovationGating) {
  control::SyntheticMotion m = MitralHrvTrace();
  MotionTrace measured = ResampleTrace(m.measured, 25.0);
  std::size_t spikes = 0;
  // One 20 mm spike a second from t = 6 s, all before the last 0.1 s (not processed:
  // nothing to score them against).
  for (std::size_t i = 150; i + 5 < measured.size(); i += 25, ++spikes)
    measured.position_mm[i] += 20.0;
  const MotionTrace truth = TruthOf(m);
  PredictionRunOptions o;
  o.truth = &truth;
  const PredictionRun r = RunPrediction(measured, o);
  EXPECT_GE(r.rejected, spikes);
  EXPECT_LE(r.rejected, spikes + spikes / 5);
  EXPECT_EQ(r.initialisations, 1u);
  EXPECT_LT(r.ekf.rms_mm, 0.6);  // spikes of 20 mm left no mark
}

TEST(HeartbeatEkf, CoastsThroughMissingFramesAndReinitialisesAfterALongGap) {
  const control::SyntheticMotion m = MitralHrvTrace();
  const MotionTrace all = ResampleTrace(m.measured, 25.0);
  auto without = [&](double from, double to) {
    MotionTrace t = all;
    t.t_s.clear();
    t.position_mm.clear();
    for (std::size_t i = 0; i < all.size(); ++i) {
      if (all.t_s[i] < from || all.t_s[i] > to) {
        t.t_s.push_back(all.t_s[i]);
        t.position_mm.push_back(all.position_mm[i]);
      }
    }
    return t;
  };
  const MotionTrace truth = TruthOf(m);
  PredictionRunOptions o;
  o.truth = &truth;
  // 0.3 s without volumes: coasted, no re-initialisation, still accurate.
  const PredictionRun short_gap = RunPrediction(without(20.0, 20.3), o);
  EXPECT_EQ(short_gap.gaps, 1u);
  EXPECT_EQ(short_gap.initialisations, 1u);
  EXPECT_LT(short_gap.ekf.rms_mm, 0.5);
  // 6 s without volumes: the phase is lost and the filter starts again.
  const PredictionRun long_gap = RunPrediction(without(15.0, 21.0), o);
  EXPECT_EQ(long_gap.initialisations, 2u);
  // It holds the newest measurement for the 4 s of re-initialisation, then predicts again.
  EXPECT_LT(long_gap.ekf.rms_mm, 0.5 * long_gap.baselines.front().rms_mm);
}

// Sparse measurements (most frames lost) span the initial window with too few samples to
// fit a heartbeat: the filter keeps buffering (holding the newest) instead of failing, and
// initialises once enough have come.
TEST(HeartbeatEkf, WaitsForEnoughSamplesWhenFramesAreSparse) {
  HeartbeatEkf ekf;
  double t = 0.0;
  for (int i = 0; i < 12; ++i, t += 0.7) {
    EXPECT_EQ(ekf.Process(t, 40.0 + 5.0 * std::cos(2 * std::numbers::pi * 1.1 * t)),
              UpdateResult::kBuffering)
        << t;
    EXPECT_DOUBLE_EQ(ekf.Predict(t + 0.1), 40.0 + 5.0 * std::cos(2 * std::numbers::pi * 1.1 * t));
  }
  EXPECT_FALSE(ekf.initialised());
  UpdateResult last = UpdateResult::kBuffering;
  for (int i = 0; i < 200 && !ekf.initialised(); ++i, t += 0.04)
    last = ekf.Process(t, 40.0 + 5.0 * std::cos(2 * std::numbers::pi * 1.1 * t));
  EXPECT_TRUE(ekf.initialised());
  EXPECT_EQ(last, UpdateResult::kInitialised);
  EXPECT_NEAR(ekf.rate_hz(), 1.1, 0.02);
}

TEST(HeartbeatEkf, ReinitialisesWhenTheTargetJumps) {
  const control::SyntheticMotion m = MitralHrvTrace();
  MotionTrace measured = ResampleTrace(m.measured, 25.0);
  for (std::size_t i = 0; i < measured.size(); ++i) {
    if (measured.t_s[i] >= 20.0) measured.position_mm[i] += 15.0;  // the probe moved
  }
  HeartbeatEkf ekf;
  int lost = 0;
  double last_error = 0.0;
  for (std::size_t i = 0; i < measured.size(); ++i) {
    if (ekf.Process(measured.t_s[i], measured.position_mm[i]) == UpdateResult::kLost) ++lost;
    if (i + 2 < measured.size() && ekf.initialised()) {
      last_error = std::abs(ekf.Predict(measured.t_s[i + 2]) - measured.position_mm[i + 2]);
    }
  }
  EXPECT_EQ(lost, 1);
  EXPECT_EQ(ekf.initialisations(), 2u);
  EXPECT_LT(last_error, 2.0);
}

TEST(HeartbeatEkf, BadInputIsAnError) {
  HeartbeatEkf ekf;
  ekf.Update(0.0, 1.0);
  ExpectContains(InvalidArgumentMessage([&] { ekf.Update(0.5, std::nan("")); }), "NaN");
  ExpectContains(InvalidArgumentMessage([&] { ekf.Update(0.0, 1.0); }), "strictly increasing");
  HeartbeatEkfOptions o;
  o.harmonics = 13;
  ExpectContains(InvalidArgumentMessage([&] { HeartbeatEkf{o}; }), "harmonics");
  o = {};
  o.init_window_s = 1.0;  // below the parameter's bound (1.7 s: one beat at 36 bpm)
  ExpectContains(InvalidArgumentMessage([&] { HeartbeatEkf{o}; }),
                 "parameter 'predictor.init_window_s' = 1: outside its bounds [1.7, 30] s");
  o.min_rate_hz = 0.5;
  o.init_window_s = 1.8;  // within the bound, yet less than one beat at 30 bpm
  ExpectContains(InvalidArgumentMessage([&] { HeartbeatEkf{o}; }), "one beat");
}

TEST(PredictionRun, TooShortTracesAreErrors) {
  const control::SyntheticMotion m = MitralHrvTrace();
  MotionTrace shortened = m.measured;
  shortened.t_s.resize(750);  // 3 s
  shortened.position_mm.resize(750);
  ExpectContains(InvalidArgumentMessage([&] { RunPrediction(shortened, {}); }), "needs more than");
  PredictionRunOptions o;
  o.latency_s = -0.1;
  ExpectContains(InvalidArgumentMessage([&] { RunPrediction(m.measured, o); }), "--latency");
}

}  // namespace
}  // namespace echoservo::estimation
