// The truncated Fourier series motion model: evaluation against the defining sum,
// derivatives against finite differences, the period fit, and validation.
//
// Tolerances:
//  - Evaluate uses an angle-addition recurrence instead of one sin/cos per harmonic;
//    each step of the recurrence adds a few ulps of rotation error, so after N ≤ 30
//    harmonics the error is a few hundred ulps of the term's scale Σ|c_k|(k·ω)^p
//    (p = 0, 1, 2 for position, velocity, acceleration). 1e-9 of that scale is far
//    above roundoff and far below any real mistake (a wrong sign or factor k).
//  - Central differences with step h have truncation error h²/6·max|x'''| (velocity)
//    and h²/6·max|x''''| (acceleration); for a Fourier series max|x^(p)| ≤
//    Σ|c_k|(kω)^p with |c_k| = √(a_k² + b_k²). Roundoff adds ≈ ε·scale/h.
#include "estimation/fourier_motion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace echoservo::estimation {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

FourierMotion RandomMotion(std::mt19937_64& rng, int harmonics) {
  std::uniform_real_distribution<double> coef(-2.0, 2.0);
  std::uniform_real_distribution<double> freq(0.5, 3.0);
  std::uniform_real_distribution<double> angle(-std::numbers::pi, std::numbers::pi);
  FourierMotion m;
  m.t0_s = coef(rng);
  m.phase0_rad = angle(rng);
  m.frequency_hz = freq(rng);
  m.offset_mm = coef(rng);
  for (int k = 0; k < harmonics; ++k) {
    m.cos_mm.push_back(coef(rng));
    m.sin_mm.push_back(coef(rng));
  }
  return m;
}

// Σ |c_k| (k ω)^p: a bound on the p-th derivative of the harmonic part.
double DerivativeScale(const FourierMotion& m, int p) {
  const double w = 2.0 * std::numbers::pi * m.frequency_hz;
  double s = p == 0 ? std::abs(m.offset_mm) : 0.0;
  for (std::size_t i = 0; i < m.harmonics(); ++i) {
    const double k = static_cast<double>(i + 1);
    s += std::hypot(m.cos_mm[i], m.sin_mm[i]) * std::pow(k * w, p);
  }
  return s;
}

// The defining sum, one sin/cos per harmonic.
MotionSample DirectSum(const FourierMotion& m, double t) {
  const double w = 2.0 * std::numbers::pi * m.frequency_hz;
  const double phase = w * (t - m.t0_s) + m.phase0_rad;
  MotionSample s{m.offset_mm, 0.0, 0.0};
  for (std::size_t i = 0; i < m.harmonics(); ++i) {
    const double k = static_cast<double>(i + 1);
    const double c = std::cos(k * phase);
    const double sn = std::sin(k * phase);
    s.position_mm += m.cos_mm[i] * c + m.sin_mm[i] * sn;
    s.velocity_mm_s += k * w * (-m.cos_mm[i] * sn + m.sin_mm[i] * c);
    s.acceleration_mm_s2 += -k * k * w * w * (m.cos_mm[i] * c + m.sin_mm[i] * sn);
  }
  return s;
}

TEST(FourierMotionTest, EvaluateMatchesDirectSumForRandomCoefficients) {
  std::mt19937_64 rng(20240601);
  std::uniform_real_distribution<double> time(-5.0, 5.0);
  for (int trial = 0; trial < 50; ++trial) {
    const FourierMotion m = RandomMotion(rng, 1 + trial % 30);
    const double tol_p = 1e-9 * DerivativeScale(m, 0);
    const double tol_v = 1e-9 * DerivativeScale(m, 1);
    const double tol_a = 1e-9 * DerivativeScale(m, 2);
    for (int i = 0; i < 40; ++i) {
      const double t = time(rng);
      const MotionSample got = m.Evaluate(t);
      const MotionSample want = DirectSum(m, t);
      ASSERT_NEAR(got.position_mm, want.position_mm, tol_p) << "N=" << m.harmonics() << " t=" << t;
      ASSERT_NEAR(got.velocity_mm_s, want.velocity_mm_s, tol_v)
          << "N=" << m.harmonics() << " t=" << t;
      ASSERT_NEAR(got.acceleration_mm_s2, want.acceleration_mm_s2, tol_a)
          << "N=" << m.harmonics() << " t=" << t;
      ASSERT_DOUBLE_EQ(m.Position(t), got.position_mm);
    }
  }
}

TEST(FourierMotionTest, SingleHarmonicIsTheTextbookSinusoid) {
  FourierMotion m;
  m.frequency_hz = 1.25;
  m.offset_mm = 0.5;
  m.cos_mm = {0.0};
  m.sin_mm = {3.0};
  const double w = 2.0 * std::numbers::pi * 1.25;
  for (double t : {0.0, 0.1, 0.2, 0.37, 0.8}) {
    const MotionSample s = m.Evaluate(t);
    EXPECT_NEAR(s.position_mm, 0.5 + 3.0 * std::sin(w * t), 1e-12);
    EXPECT_NEAR(s.velocity_mm_s, 3.0 * w * std::cos(w * t), 1e-11);
    EXPECT_NEAR(s.acceleration_mm_s2, -3.0 * w * w * std::sin(w * t), 1e-10);
  }
}

TEST(FourierMotionTest, EmptySeriesIsTheOffset) {
  FourierMotion m;
  m.offset_mm = -2.5;
  const MotionSample s = m.Evaluate(3.3);
  EXPECT_EQ(s.position_mm, -2.5);
  EXPECT_EQ(s.velocity_mm_s, 0.0);
  EXPECT_EQ(s.acceleration_mm_s2, 0.0);
}

TEST(FourierMotionTest, DerivativesMatchFiniteDifferences) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> time(-2.0, 2.0);
  for (int trial = 0; trial < 20; ++trial) {
    const FourierMotion m = RandomMotion(rng, 1 + trial % 12);
    const double h = 1e-5 / m.frequency_hz;
    // Truncation h²/6·max|x'''| (resp. x''''), roundoff ~ 4ε·scale/h, doubled for margin.
    const double tol_v =
        2.0 * (h * h / 6.0 * DerivativeScale(m, 3) + 4.0 * kEps * DerivativeScale(m, 0) / h);
    const double tol_a =
        2.0 * (h * h / 6.0 * DerivativeScale(m, 4) + 4.0 * kEps * DerivativeScale(m, 1) / h);
    for (int i = 0; i < 20; ++i) {
      const double t = time(rng);
      const MotionSample s = m.Evaluate(t);
      const MotionSample plus = m.Evaluate(t + h);
      const MotionSample minus = m.Evaluate(t - h);
      ASSERT_NEAR(s.velocity_mm_s, (plus.position_mm - minus.position_mm) / (2.0 * h), tol_v);
      ASSERT_NEAR(s.acceleration_mm_s2, (plus.velocity_mm_s - minus.velocity_mm_s) / (2.0 * h),
                  tol_a);
    }
  }
}

TEST(FourierMotionTest, IsPeriodicInOnePeriod) {
  std::mt19937_64 rng(99);
  const FourierMotion m = RandomMotion(rng, 8);
  const double period = 1.0 / m.frequency_hz;
  for (double t : {-1.0, 0.0, 0.3, 2.7}) {
    const MotionSample a = m.Evaluate(t);
    const MotionSample b = m.Evaluate(t + 3.0 * period);
    EXPECT_NEAR(a.position_mm, b.position_mm, 1e-9 * DerivativeScale(m, 0));
    EXPECT_NEAR(a.velocity_mm_s, b.velocity_mm_s, 1e-9 * DerivativeScale(m, 1));
    EXPECT_NEAR(a.acceleration_mm_s2, b.acceleration_mm_s2, 1e-9 * DerivativeScale(m, 2));
  }
}

// A band-limited signal (harmonics ≤ N) sampled at n ≥ 2N+1 points has no aliasing, so
// the discrete Fourier sums return its coefficients exactly (to roundoff).
TEST(FourierMotionTest, FromPeriodSamplesRecoversBandLimitedCoefficients) {
  std::mt19937_64 rng(3);
  for (int n_harm : {1, 3, 5, 10}) {
    FourierMotion truth = RandomMotion(rng, n_harm);
    truth.t0_s = 0.0;
    truth.phase0_rad = 0.0;
    for (int n : {2 * n_harm + 1, 2 * n_harm + 2, 64, 257}) {
      std::vector<double> samples(static_cast<std::size_t>(n));
      for (int i = 0; i < n; ++i) {
        samples[static_cast<std::size_t>(i)] =
            truth.Position(static_cast<double>(i) / n / truth.frequency_hz);
      }
      // Fit more harmonics than the signal has when the sample count allows: the extra
      // coefficients must come out zero.
      const int fit = std::min((n - 1) / 2, n_harm + 3);
      const FourierMotion m = FourierMotion::FromPeriodSamples(samples, fit, truth.frequency_hz);
      ASSERT_EQ(m.harmonics(), static_cast<std::size_t>(fit));
      ASSERT_EQ(m.sin_mm.size(), static_cast<std::size_t>(fit));
      EXPECT_EQ(m.frequency_hz, truth.frequency_hz);
      const double tol = 1e-12 * n * DerivativeScale(truth, 0);
      EXPECT_NEAR(m.offset_mm, truth.offset_mm, tol) << "N=" << n_harm << " n=" << n;
      for (int k = 0; k < fit; ++k) {
        const double a = k < n_harm ? truth.cos_mm[static_cast<std::size_t>(k)] : 0.0;
        const double b = k < n_harm ? truth.sin_mm[static_cast<std::size_t>(k)] : 0.0;
        EXPECT_NEAR(m.cos_mm[static_cast<std::size_t>(k)], a, tol) << "a_" << k + 1 << " n=" << n;
        EXPECT_NEAR(m.sin_mm[static_cast<std::size_t>(k)], b, tol) << "b_" << k + 1 << " n=" << n;
      }
    }
  }
}

TEST(FourierMotionTest, FromPeriodSamplesOfAConstantIsTheOffset) {
  const FourierMotion m = FourierMotion::FromPeriodSamples(std::vector<double>(16, 4.25), 3, 2.0);
  EXPECT_NEAR(m.offset_mm, 4.25, 1e-14);
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(m.cos_mm[k], 0.0, 1e-13);
    EXPECT_NEAR(m.sin_mm[k], 0.0, 1e-13);
  }
  EXPECT_EQ(m.harmonics(), 3u);
  const FourierMotion zero = FourierMotion::FromPeriodSamples({1.0, 2.0, 3.0}, 0, 1.0);
  EXPECT_EQ(zero.harmonics(), 0u);
  EXPECT_NEAR(zero.offset_mm, 2.0, 1e-15);
}

TEST(FourierMotionTest, FromPeriodSamplesRejectsTooFewSamples) {
  EXPECT_THROW(FourierMotion::FromPeriodSamples(std::vector<double>(6, 0.0), 3, 1.0),
               std::invalid_argument);
  EXPECT_NO_THROW(FourierMotion::FromPeriodSamples(std::vector<double>(7, 0.0), 3, 1.0));
  EXPECT_THROW(FourierMotion::FromPeriodSamples({}, 0, 1.0), std::invalid_argument);
  EXPECT_THROW(FourierMotion::FromPeriodSamples(std::vector<double>(8, 0.0), -1, 1.0),
               std::invalid_argument);
  EXPECT_THROW(FourierMotion::FromPeriodSamples(std::vector<double>(8, 0.0), 2, 0.0),
               std::invalid_argument);
}

// Expects `m.Validate()` to throw std::invalid_argument mentioning `needle`.
void ExpectInvalid(const FourierMotion& m, const std::string& needle) {
  try {
    m.Validate();
    ADD_FAILURE() << "Validate() accepted an invalid motion (expected '" << needle << "')";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(FourierMotionTest, ValidateRejectsInvalidMotions) {
  FourierMotion good;
  good.cos_mm = {1.0, 0.5};
  good.sin_mm = {0.0, -0.5};
  EXPECT_NO_THROW(good.Validate());

  FourierMotion m = good;
  m.sin_mm.pop_back();
  ExpectInvalid(m, "count");

  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (double f : {0.0, -1.0, nan, inf}) {
    m = good;
    m.frequency_hz = f;
    ExpectInvalid(m, "frequency_hz");
  }
  for (double bad : {nan, inf}) {
    m = good;
    m.cos_mm[1] = bad;
    ExpectInvalid(m, "non-finite");
    m = good;
    m.sin_mm[0] = bad;
    ExpectInvalid(m, "non-finite");
    m = good;
    m.offset_mm = bad;
    ExpectInvalid(m, "non-finite");
    m = good;
    m.t0_s = bad;
    ExpectInvalid(m, "non-finite");
    m = good;
    m.phase0_rad = bad;
    ExpectInvalid(m, "non-finite");
  }
  m = good;
  m.valid_until_s = nan;
  ExpectInvalid(m, "non-finite");
  m = good;
  m.valid_until_s = inf;  // valid forever
  EXPECT_NO_THROW(m.Validate());
}

TEST(FourierMotionTest, ValidAtHonoursTheHorizon) {
  FourierMotion m;
  EXPECT_TRUE(m.ValidAt(1e12));
  m.valid_until_s = 2.0;
  EXPECT_TRUE(m.ValidAt(1.999));
  EXPECT_TRUE(m.ValidAt(2.0));
  EXPECT_FALSE(m.ValidAt(2.001));
}

}  // namespace
}  // namespace echoservo::estimation
