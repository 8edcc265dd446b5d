// The least-squares autoregressive predictor (estimation/ls_ar_predictor.h): it learns a
// periodic motion and predicts through the latency at 20, 25 and 200 Hz (lags strided, the
// horizon exact), and rejects bad input. Traces are made here (plain sines), sharing no code
// with the predictor.
#include "estimation/ls_ar_predictor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tests/test_util/expect_error.h"

namespace echoservo::estimation {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

// Two harmonics of a 1.2 Hz beat, mm.
double LsBeat(double t) {
  const double w = 2.0 * std::numbers::pi * 1.2;
  return 4.0 * std::sin(w * t) + 1.5 * std::cos(2.0 * w * t + 0.4);
}

TEST(LsArPredictor, LearnsAPeriodicMotionAndPredictsThroughTheLatency) {
  LsArPredictor ar;  // 0.1 s ahead: 2 samples at 20 Hz
  const double rate = 20.0;
  double ss_ar = 0.0, ss_zoh = 0.0;
  for (int i = 0; i < 20 * 30; ++i) {
    const double t = i / rate;
    ar.Update(t, LsBeat(t));
    if (t < 15.0) continue;  // scored on the second half only
    ss_ar += std::pow(ar.Predict(t + 0.1) - LsBeat(t + 0.1), 2);
    ss_zoh += std::pow(LsBeat(t) - LsBeat(t + 0.1), 2);
  }
  EXPECT_EQ(ar.horizon_steps(), 2);
  EXPECT_EQ(ar.stride(), 1);
  EXPECT_TRUE(ar.ready());
  // Two harmonics: a linear predictor needs ≥ 4 lags (plus the offset) to be exact; the
  // a-priori choice takes at least that.
  EXPECT_GE(ar.order(), 5);
  // Noise-free and exactly periodic: what is left is the ridge's numerical error, far below
  // the hold's.
  EXPECT_LT(std::sqrt(ss_ar / ss_zoh), 0.05);
}

TEST(LsArPredictor, AtHighRatesLagsAreStridedAndTheHorizonIsExact) {
  // 200 Hz: lags 4 samples apart (≤ 50 Hz); a 0.1 s horizon is 20 samples; at 25 Hz it is
  // 2.5 samples, the target interpolated between them (not rounded to 3).
  for (double rate : {200.0, 25.0}) {
    LsArPredictor ar;
    double ss_ar = 0.0, ss_zoh = 0.0;
    for (int i = 0; i < static_cast<int>(rate * 30); ++i) {
      const double t = i / rate;
      ar.Update(t, LsBeat(t));
      if (t < 15.0) continue;
      ss_ar += std::pow(ar.Predict(t + 0.1) - LsBeat(t + 0.1), 2);
      ss_zoh += std::pow(LsBeat(t) - LsBeat(t + 0.1), 2);
    }
    EXPECT_EQ(ar.stride(), rate > 50.0 ? 4 : 1) << rate;
    EXPECT_EQ(ar.horizon_steps(), rate > 50.0 ? 20 : 3) << rate;
    EXPECT_LT(std::sqrt(ss_ar / ss_zoh), 0.05) << rate;
  }
}

// The hold before training and after a gap, the filled dropped sample and the clamp to the
// recent range: typed tests over both predictors in ar_predictor_test.cc.

TEST(LsArPredictor, RejectsBadInput) {
  LsArPredictorOptions o;
  o.max_history_s = 0.0;
  ExpectContains(InvalidArgumentMessage([&] { LsArPredictor{o}; }),
                 "least-squares autoregressive predictor");
  LsArPredictor ar;
  ar.Update(1.0, 0.0);
  ExpectContains(InvalidArgumentMessage([&] { ar.Update(1.0, 1.0); }), "strictly increasing");
  ExpectContains(InvalidArgumentMessage([&] { ar.Update(2.0, NAN); }), "NaN");
}

}  // namespace
}  // namespace echoservo::estimation
