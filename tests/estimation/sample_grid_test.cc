// The sampling grid of the autoregressive predictors (estimation/sample_grid.h): the nominal
// interval is the median of the first eight, dropped samples are told apart from gaps and
// irregular intervals, and bad input is refused with the owner's name.
#include "estimation/sample_grid.h"

#include <gtest/gtest.h>

#include <cmath>
#include <deque>

#include "tests/test_util/expect_error.h"

namespace echoservo::estimation {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

TEST(SampleGrid, LearnsTheMedianIntervalThenClassifies) {
  SampleGrid g("test predictor");
  // Eight intervals around 40 ms, one of them an outlier: the median ignores it.
  const double t[] = {0.0, 0.04, 0.08, 0.121, 0.16, 0.30, 0.34, 0.379, 0.42};
  for (int i = 0; i < 8; ++i) EXPECT_EQ(g.Accept(t[i], 0.0), SampleGrid::Step::kLearning) << i;
  EXPECT_EQ(g.Accept(t[8], 0.0), SampleGrid::Step::kLearned);
  EXPECT_NEAR(g.dt_s(), 0.04, 0.0015);
  EXPECT_EQ(g.Accept(0.46, 0.0), SampleGrid::Step::kNext);
  EXPECT_EQ(g.Accept(0.58, 0.0), SampleGrid::Step::kDropped);  // 3 intervals: 2 dropped
  EXPECT_EQ(g.dropped(), 2);
  EXPECT_EQ(g.Accept(0.74, 0.0), SampleGrid::Step::kDropped);  // 4 intervals: 3 dropped
  EXPECT_EQ(g.dropped(), 3);
  EXPECT_EQ(g.Accept(0.94, 0.0), SampleGrid::Step::kBroken);   // 5 intervals: too many to fill
  EXPECT_EQ(g.Accept(1.007, 0.0), SampleGrid::Step::kBroken);  // 1.7 intervals: off the grid
  EXPECT_EQ(g.Accept(1.5, 0.0), SampleGrid::Step::kBroken);    // a gap
  EXPECT_EQ(g.Accept(1.51, 0.0), SampleGrid::Step::kBroken);   // a quarter interval
  EXPECT_DOUBLE_EQ(g.last_t_s(), 1.51);
  EXPECT_NEAR(g.dt_s(), 0.04, 0.0015);  // the nominal interval is not relearned
}

TEST(SampleGrid, FillsDroppedSamplesLinearly) {
  std::deque<double> h = {0.0, 1.0};
  int learned = 0;
  FillDropped(h, 5.0, 3, 4, [&] { ++learned; });
  // Three samples between 1 and 5: 2, 3, 4; the history kept to four.
  ASSERT_EQ(h.size(), 4u);
  EXPECT_NEAR(h[1], 2.0, 1e-12);
  EXPECT_NEAR(h[2], 3.0, 1e-12);
  EXPECT_NEAR(h[3], 4.0, 1e-12);
  EXPECT_EQ(learned, 3);
  EXPECT_NEAR(TowardsHorizon(1.0, 3.0, 10.0, 0.1, 10.05), 2.0, 1e-12);
  EXPECT_DOUBLE_EQ(TowardsHorizon(1.0, 3.0, 10.0, 0.1, 10.5), 3.0);  // held past the horizon
  EXPECT_DOUBLE_EQ(TowardsHorizon(1.0, 3.0, 10.0, 0.0, 10.5), 1.0);  // no horizon: hold
}

TEST(SampleGrid, RefusesBadInputNamingItsOwner) {
  SampleGrid g("my predictor");
  g.Accept(1.0, 0.0);
  const std::string m = InvalidArgumentMessage([&] { g.Accept(1.0, 0.0); });
  ExpectContains(m, "my predictor");
  ExpectContains(m, "strictly increasing");
  ExpectContains(InvalidArgumentMessage([&] { g.Accept(2.0, NAN); }), "NaN");
  ExpectContains(InvalidArgumentMessage([&] { g.Accept(INFINITY, 0.0); }), "infinite");
  EXPECT_EQ(g.Accept(2.0, 0.0), SampleGrid::Step::kLearning);  // nothing changed by the refusals
}

}  // namespace
}  // namespace echoservo::estimation
