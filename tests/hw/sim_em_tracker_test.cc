// The simulated EM tracker (hw/sim_em_tracker.h): rate, clock offset, frame, noise level and
// drop-out rate against their settings, with tolerances from the sampling statistics.
#include "hw/sim_em_tracker.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace echoservo::hw {
namespace {

TEST(SimEmTracker, SamplesAtItsRateOnItsClockInItsFrameWithTheSetNoiseAndDropouts) {
  SimEmTrackerOptions o;
  o.rate_hz = 40.0;
  o.noise_rms_mm = 0.3;
  o.clock_offset_s = 0.5;
  o.dropout_probability = 0.05;
  o.image_to_em =
      Eigen::Translation3d(10, -20, 30) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ());
  SimEmTracker em(o, 2.0);
  const Eigen::Vector3d tip(1.0, 2.0, 60.0);
  const int n = 20000;
  double sq = 0.0;
  int valid = 0;
  for (int k = 0; k < n; ++k) {
    EXPECT_NEAR(em.next_sample_s(), 2.0 + k / 40.0, 1e-9);
    const formats::EmSample r = em.Sample(tip);
    EXPECT_NEAR(r.t_s, 2.5 + k / 40.0, 1e-9);
    if (!r.valid) continue;
    ++valid;
    sq += (r.position_mm - o.image_to_em * tip).squaredNorm();
  }
  EXPECT_EQ(em.samples(), static_cast<std::uint64_t>(n));
  EXPECT_EQ(em.dropouts(), static_cast<std::uint64_t>(n - valid));
  // Drop-outs: binomial, σ = √(n p (1 − p)) ≈ 31; 5σ.
  EXPECT_NEAR(n - valid, 0.05 * n, 5 * std::sqrt(n * 0.05 * 0.95));
  // RMS of 3-D noise: relative σ of a χ²₃ₙ mean is √(2/(3n)) ≈ 0.6 %; 5σ on the RMS ≈ 1.5 %.
  EXPECT_NEAR(std::sqrt(sq / valid), 0.3, 0.3 * 0.02);
}

TEST(SimEmTracker, BadOptions) {
  SimEmTrackerOptions o;
  o.rate_hz = 0;
  EXPECT_THROW(SimEmTracker{o}, std::invalid_argument);
  o = {};
  o.image_to_em.linear() *= 2.0;  // not rigid
  EXPECT_THROW(SimEmTracker{o}, std::invalid_argument);
  o = {};
  o.dropout_probability = 0.9;
  EXPECT_THROW(SimEmTracker{o}, std::invalid_argument);
}

}  // namespace
}  // namespace echoservo::hw
