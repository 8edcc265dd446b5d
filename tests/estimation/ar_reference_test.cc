// The autoregressive reference (estimation/ar_reference.h): exact on a noise-free periodic
// motion, its order chosen by cross-validation (more lags for a richer shape, the hold's
// single offset for white noise), strided lags at high rates, the split and the scored
// instants, a gap held over, and a trace too short named with the length it needs. Traces
// are made here from sines and a seeded noise source.
#include "estimation/ar_reference.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "tests/test_util/expect_error.h"

namespace echoservo::estimation {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

MotionTrace RefSines(double rate_hz, double duration_s, int harmonics, double noise_mm = 0.0) {
  MotionTrace m;
  m.source = "sines";
  m.column = "position";
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, noise_mm > 0.0 ? noise_mm : 1.0);
  const double w = 2.0 * std::numbers::pi * 1.25;
  for (int i = 0; i < static_cast<int>(rate_hz * duration_s); ++i) {
    const double t = i / rate_hz;
    double x = 0.0;
    for (int k = 1; k <= harmonics; ++k) x += 4.0 / k * std::sin(k * w * t + 0.5 * k);
    m.t_s.push_back(t);
    m.position_mm.push_back(x + (noise_mm > 0.0 ? n(rng) : 0.0));
  }
  return m;
}

// RMS of the reference's predictions against the noise-free motion at t + L.
double ReferenceRms(const ArReference& r, const MotionTrace& truth, double latency_s) {
  const TraceInterpolator at(truth);
  double ss = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < r.t_s.size(); ++i) {
    double x = 0.0;
    if (!at.At(r.t_s[i] + latency_s, x)) continue;
    ss += std::pow(r.predicted_mm[i] - x, 2);
    ++n;
  }
  return std::sqrt(ss / static_cast<double>(n));
}

TEST(ArReference, ExactOnAPeriodicMotionWithTheOrderItNeeds) {
  const MotionTrace one = RefSines(20.0, 30.0, 1);
  const MotionTrace four = RefSines(20.0, 30.0, 4);
  ArReferenceOptions o;
  const ArReference r1 = FitArReference(one, o);
  const ArReference r4 = FitArReference(four, o);
  // A sinusoid is a 2-lag recursion (+ offset: order ≥ 3); four harmonics need ≥ 8 lags.
  EXPECT_GE(r1.order, 3);
  EXPECT_GE(r4.order, 9);
  EXPECT_LT(ReferenceRms(r1, one, o.latency_s), 1e-3);
  EXPECT_LT(ReferenceRms(r4, four, o.latency_s), 1e-2);
  // Split at the middle; every second-half measurement is scored; none held (no gaps).
  EXPECT_NEAR(r4.split_s, 0.5 * four.t_s.back(), 1e-12);
  EXPECT_EQ(r4.held, 0u);
  EXPECT_EQ(r4.scored, r4.t_s.size());
  EXPECT_GE(r4.t_s.front(), r4.split_s);
  EXPECT_EQ(r4.candidates.size(), r4.validation_rms_mm.size());
}

TEST(ArReference, OnWhiteNoiseItPredictsTheMeanNotTheNewestSample) {
  // Nothing to predict but the mean: the hold's error is σ√2, the mean's σ. The offset-free
  // model reaches the mean by averaging lags, so cross-validation takes many of them and
  // the error falls towards σ√(1 + 1/p).
  MotionTrace m = RefSines(25.0, 40.0, 1);
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  for (double& x : m.position_mm) x = n(rng);
  const ArReference r = FitArReference(m, {});
  EXPECT_GE(r.order, 8);
  MotionTrace zero = m;
  for (double& x : zero.position_mm) x = 0.0;  // the truth: white noise's mean
  const double rms = std::sqrt(std::pow(ReferenceRms(r, zero, 0.1), 2) + 1.0);  // + σ² of x
  EXPECT_LT(rms, 1.15);  // near σ(1 + 1/(2p)), far below the hold's √2
}

TEST(ArReference, StridedAtHighRatesAndHeldAfterAGap) {
  MotionTrace m = RefSines(200.0, 20.0, 3);
  // A 0.5 s gap in the second half: the instants right after it have no history.
  MotionTrace g = m;
  g.t_s.clear();
  g.position_mm.clear();
  for (std::size_t i = 0; i < m.size(); ++i) {
    if (m.t_s[i] > 14.0 && m.t_s[i] < 14.5) continue;
    g.t_s.push_back(m.t_s[i]);
    g.position_mm.push_back(m.position_mm[i]);
  }
  const ArReference full = FitArReference(m, {});
  EXPECT_EQ(full.stride, 4);  // 200 Hz → lags at 50 Hz
  EXPECT_EQ(full.held, 0u);
  EXPECT_LT(ReferenceRms(full, m, 0.1), 0.05);
  const ArReference r = FitArReference(g, {});
  EXPECT_GT(r.held, 0u);
  // The instants within the chosen order's lag span after the gap.
  EXPECT_EQ(r.held, static_cast<std::size_t>((r.order - 1) * r.stride));
}

TEST(ArReference, ATraceTooShortSaysHowLongItMustBe) {
  const MotionTrace m = RefSines(25.0, 6.0, 2);
  ExpectContains(InvalidArgumentMessage([&] { FitArReference(m, {}); }),
                 "sines: the trace spans 6.0 s; the autoregressive reference needs at least 8.2 s");
  ArReferenceOptions bad;
  bad.folds = 1;
  ExpectContains(InvalidArgumentMessage([&] { FitArReference(RefSines(25.0, 30.0, 1), bad); }),
                 "folds >= 2");
}

}  // namespace
}  // namespace echoservo::estimation
