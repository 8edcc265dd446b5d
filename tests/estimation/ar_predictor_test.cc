// The adaptive direct-horizon autoregressive predictor (estimation/ar_predictor.h): it
// learns a periodic motion and predicts through the latency, holds until trained and after
// a gap, stays inside the recent range, and rejects bad input. Traces are made here (plain
// sines and steps), sharing no code with the predictor.
#include "estimation/ar_predictor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "estimation/ls_ar_predictor.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::estimation {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

// Two harmonics of a 1.2 Hz beat, mm.
double Beat(double t) {
  const double w = 2.0 * std::numbers::pi * 1.2;
  return 4.0 * std::sin(w * t) + 1.5 * std::cos(2.0 * w * t + 0.4);
}

TEST(ArPredictor, LearnsAPeriodicMotionAndPredictsThroughTheLatency) {
  ArPredictor ar;  // 0.1 s ahead: 2 samples at 20 Hz
  const double rate = 20.0;
  double ss_ar = 0.0, ss_zoh = 0.0;
  for (int i = 0; i < 20 * 30; ++i) {
    const double t = i / rate;
    ar.Update(t, Beat(t));
    if (t < 15.0) continue;  // scored on the second half only
    ss_ar += std::pow(ar.Predict(t + 0.1) - Beat(t + 0.1), 2);
    ss_zoh += std::pow(Beat(t) - Beat(t + 0.1), 2);
  }
  EXPECT_EQ(ar.order(), 20);  // one second of history at 20 Hz
  EXPECT_EQ(ar.horizon_steps(), 2);
  EXPECT_TRUE(ar.ready());
  // Noise-free and exactly periodic: a linear predictor of order ≥ 4 is exact, so what is
  // left is the forgetting's numerical error, far below the hold's.
  EXPECT_LT(std::sqrt(ss_ar / ss_zoh), 0.05);
}

// What both autoregressive predictors (the recursive one here and the least-squares one,
// estimation/ls_ar_predictor.h) promise alike: the hold before training and after a gap, the
// filled dropped sample (their shared sampling grid), and the clamp to the recent range.
template <typename T>
class BothArPredictors : public ::testing::Test {};
using ArPredictorTypes = ::testing::Types<ArPredictor, LsArPredictor>;
TYPED_TEST_SUITE(BothArPredictors, ArPredictorTypes);

TYPED_TEST(BothArPredictors, HoldsUntilTrainedAndAfterAGap) {
  TypeParam ar;
  for (int i = 0; i < 20; ++i) {
    ar.Update(i * 0.04, Beat(i * 0.04));
    EXPECT_DOUBLE_EQ(ar.Predict(i * 0.04 + 0.1), Beat(i * 0.04));  // zero-order hold
  }
  for (int i = 20; i < 400; ++i) ar.Update(i * 0.04, Beat(i * 0.04));
  ASSERT_TRUE(ar.ready());
  // A gap of 25 intervals: the lags are lost, it holds again until it has order samples.
  ar.Update(425 * 0.04, 1.0);
  EXPECT_EQ(ar.history_resets(), 1u);
  EXPECT_FALSE(ar.ready());
  EXPECT_DOUBLE_EQ(ar.Predict(425 * 0.04 + 0.1), 1.0);
  // One dropped sample is filled, not a reset.
  TypeParam filled;
  for (int i = 0; i < 400; ++i)
    if (i != 300) filled.Update(i * 0.04, Beat(i * 0.04));
  EXPECT_EQ(filled.history_resets(), 0u);
  EXPECT_EQ(filled.filled_gaps(), 1u);
  EXPECT_TRUE(filled.ready());
}

TYPED_TEST(BothArPredictors, NeverLeavesTheRecentRange) {
  TypeParam ar;
  // A beat, then a sudden step of 30 mm and a ramp: whatever the weights say, the
  // prediction stays within the newest 3 s of data ± 25 % of their range.
  std::vector<double> z;
  for (int i = 0; i < 1000; ++i) {
    const double t = i * 0.04;
    double v = Beat(t) + (i >= 500 ? 30.0 : 0.0) + (i >= 700 ? 2.0 * (t - 28.0) : 0.0);
    if (i % 97 == 0) v += 50.0;  // outliers
    z.push_back(v);
    ar.Update(t, v);
    const std::size_t from = z.size() > 75 ? z.size() - 75 : 0;
    double lo = z[from], hi = z[from];
    for (std::size_t k = from; k < z.size(); ++k) {
      lo = std::min(lo, z[k]);
      hi = std::max(hi, z[k]);
    }
    const double p = ar.Predict(t + 0.1);
    ASSERT_TRUE(std::isfinite(p));
    ASSERT_GE(p, lo - 0.25 * (hi - lo) - 1e-9) << i;
    ASSERT_LE(p, hi + 0.25 * (hi - lo) + 1e-9) << i;
  }
}

TEST(ArPredictor, RejectsBadInput) {
  ArPredictorOptions o;
  o.history_s = 0.0;
  ExpectContains(InvalidArgumentMessage([&] { ArPredictor{o}; }), "autoregressive predictor");
  ArPredictor ar;
  ar.Update(1.0, 0.0);
  ExpectContains(InvalidArgumentMessage([&] { ar.Update(1.0, 1.0); }), "strictly increasing");
  ExpectContains(InvalidArgumentMessage([&] { ar.Update(2.0, NAN); }), "NaN");
}

}  // namespace
}  // namespace echoservo::estimation
