// The one scored window `demo` and `report` share (report/scored_window.h): following plus two
// beats at the run's heart rate, never less than 2 s, and a window the user gave as given.
#include "report/scored_window.h"

#include <gtest/gtest.h>

#include <cmath>

namespace echoservo::report {
namespace {

TEST(ScoredWindow, SettlesForTwoBeatsAtTheRunsRateAndAtLeastTwoSeconds) {
  EXPECT_DOUBLE_EQ(SettleTimeS(0.5), 4.0);  // 30 bpm: two beats are 4 s
  EXPECT_DOUBLE_EQ(SettleTimeS(1.0), 2.0);
  EXPECT_DOUBLE_EQ(SettleTimeS(3.0), 2.0);  // 180 bpm: the approach still takes 2 s
  EXPECT_DOUBLE_EQ(SettleTimeS(std::nullopt), kMinSettleS);
  EXPECT_DOUBLE_EQ(SettleTimeS(0.0), kMinSettleS);  // no usable rate
  EXPECT_DOUBLE_EQ(SettleTimeS(NAN), kMinSettleS);
}

TEST(ScoredWindow, OpensAfterFollowingPlusSettlingAndSaysWhy) {
  const ScoredWindow w = WindowAfterFollowing(2.35, 0.8);
  EXPECT_DOUBLE_EQ(w.following_s, 2.35);
  EXPECT_DOUBLE_EQ(w.settle_s, 2.5);
  EXPECT_DOUBLE_EQ(w.from_s, 4.85);
  EXPECT_EQ(Describe(w),
            "from 4.85 s: servo began following at 2.35 s + settling 2.50 s (2 beats at 48.0 "
            "bpm, at least 2.0 s)");
  EXPECT_EQ(Describe(WindowAfterFollowing(1.0, std::nullopt)),
            "from 3.00 s: servo began following at 1.00 s + settling 2.00 s (no heart rate "
            "stated: 2.0 s)");
  EXPECT_EQ(Describe(GivenWindow(5.0, "--from")), "from 5.00 s: --from");
  const ScoredWindow whole = WholeRun("whole run: no servo.csv");
  EXPECT_FALSE(std::isfinite(whole.from_s));
  EXPECT_EQ(Describe(whole), "whole run: no servo.csv");
}

}  // namespace
}  // namespace echoservo::report
