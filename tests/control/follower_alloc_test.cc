// The target follower inside the 1 kHz cycle allocates nothing after its warm-up: Update and
// Evaluate every cycle (following, the stale hold, the retraction, the deadline hooks) and
// Accept for each tracker estimate, counted by the replaced operator new of
// tests/control/alloc_counter.h. The ring buffers wrap several times within the counted part
// (the tip history after 2048 cycles, the response window after a window's worth of volumes).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numbers>

#include "control/target_follower.h"
#include "tests/control/alloc_counter.h"

namespace echoservo::control {
namespace {

// A target 40 + 5·cos(2π·1.2·t) mm with three harmonics, valid 0.5 s after acquisition.
TargetEstimateInput AllocTestEstimate(double acquired_s, double tip_axis_mm) {
  TargetEstimateInput e;
  e.acquired_s = acquired_s;
  e.published_s = acquired_s + 0.03;
  e.target_motion.frequency_hz = 1.2;
  e.target_motion.offset_mm = 40.0;
  e.target_motion.cos_mm = {5.0, 0.5, 0.1};
  e.target_motion.sin_mm = {0.0, 0.2, 0.0};
  e.target_motion.valid_until_s = acquired_s + 0.5;
  e.tip_axis_mm = tip_axis_mm;
  e.confidence = 0.9;
  return e;
}

TEST(FollowerAllocation, UpdateEvaluateAndAcceptAllocateNothingAfterWarmUp) {
  FollowerConfig c;
  c.estimate_scale = true;
  c.response_window_s = 0.5;  // 12 volumes at 25 vol/s: the window's ring wraps often
  TargetFollower f(c);
  // Warm-up: the first second of cycles and volumes (the estimate's harmonic vectors and the
  // response window reach their working sizes).
  const int kVolumeEvery = 40;  // 25 vol/s at 1 kHz
  double tip = 0.0;
  auto cycle = [&](int k, bool volumes) {
    const double t = k * 1e-3;
    if (volumes && k % kVolumeEvery == 0 && k > 0) {
      const double acquired = t - 0.03;
      f.Accept(AllocTestEstimate(acquired, tip + 30.0), t);
    }
    f.Update(t, tip);
    const MotionSample m = f.Evaluate(t);
    tip += (m.position_mm - tip) * 1e-3 / 0.01;  // a 10 ms first-order tip
  };
  f.Update(0.0, 0.0);
  f.Enable(0.0);
  int k = 1;
  for (; k < 1000; ++k) cycle(k, true);
  ASSERT_EQ(f.mode(), FollowerMode::kFollowing);

  // Estimates are built outside the counted part: the tracker's thread makes them.
  const std::uint64_t before = testing::ThreadAllocations();
  for (; k < 4000; ++k) cycle(k, false);  // following on the last estimate, then stale
  EXPECT_EQ(testing::ThreadAllocations(), before) << "Update/Evaluate, following and holding";
  EXPECT_NE(f.mode(), FollowerMode::kFollowing);  // it held and retracted on the way

  // Accept: volumes again, with estimates made beforehand.
  f.Enable(4.0);
  std::vector<TargetEstimateInput> estimates;
  for (int i = 0; i < 100; ++i)
    estimates.push_back(AllocTestEstimate(4.0 + i * 0.04 - 0.03, 30.0 + std::sin(i * 0.3)));
  const std::uint64_t before_accept = testing::ThreadAllocations();
  for (int i = 0; i < 100; ++i) {
    for (int j = 0; j < kVolumeEvery; ++j, ++k) {
      const double t = k * 1e-3;
      if (j == 0) f.Accept(estimates[static_cast<std::size_t>(i)], t);
      f.Update(t, tip);
      const MotionSample m = f.Evaluate(t);
      tip += (m.position_mm - tip) * 1e-3 / 0.01;
      if (i == 50 && j == 0) f.DeadlineHold(t);
      if (i == 60 && j == 0) f.DeadlineCleared(t);
      if (i == 70 && j == 0) f.DeadlineRetract(t);
      if (i == 80 && j == 0) f.Enable(t);
    }
  }
  EXPECT_EQ(testing::ThreadAllocations(), before_accept) << "Accept and the deadline hooks";
  EXPECT_GT(f.counters().accepted, 100u);
}

}  // namespace
}  // namespace echoservo::control
