// Latency histograms and cycle accounting (control/cycle_timing.h). Quantiles are checked
// against distributions whose quantiles are known in closed form: an evenly spaced grid
// (exact ranks) and an exponential sample drawn with the standard library (tolerance: one
// bin plus five standard errors of the sample quantile, sqrt(p(1−p)/n) / f(q)). Overrun
// accounting runs on synthetic times, where the deadline arithmetic is exact.
#include "control/cycle_timing.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "tests/test_util/expect_error.h"

namespace echoservo::control {
namespace {

using testing::ExpectContains;
using testing::InvalidArgumentMessage;

constexpr double kUs = 1e-6;
constexpr double kNsInUs = 1e-3;  // summaries in µs are rounded to the ns

TEST(LatencyHistogramTest, GridQuantilesFallInTheBinOfTheirRank) {
  // 1000 values at 0.5, 1.5, …, 999.5 µs: the k-th smallest is k − 0.5 µs, so the
  // p-quantile (rank ceil(p·1000)) lies in the bin whose upper edge is p·1000 µs.
  LatencyHistogram h(1 * kUs, 2e-3);
  for (int i = 0; i < 1000; ++i) h.Add((i + 0.5) * kUs);
  EXPECT_EQ(h.count(), 1000u);
  EXPECT_EQ(h.overflow(), 0u);
  EXPECT_NEAR(h.Quantile(0.5), 500 * kUs, 1e-12);
  EXPECT_NEAR(h.Quantile(0.99), 990 * kUs, 1e-12);
  EXPECT_NEAR(h.Quantile(0.999), 999 * kUs, 1e-12);
  EXPECT_NEAR(h.Quantile(0.0), 1 * kUs, 1e-12);  // the smallest value's bin
  EXPECT_DOUBLE_EQ(h.Quantile(1.0), 999.5 * kUs);
  EXPECT_DOUBLE_EQ(h.max_s(), 999.5 * kUs);
  EXPECT_NEAR(h.mean_s(), 500 * kUs, 1e-12);
}

TEST(LatencyHistogramTest, UniformIntegerMicrosecondsWithinOneBin) {
  // Values 0, 1, …, 999 µs, each on a bin edge: floating-point division may put a value in
  // the bin below, so the quantiles are good to one bin.
  LatencyHistogram h(1 * kUs, 0.05);
  for (int i = 0; i < 1000; ++i) h.Add(i * kUs);
  EXPECT_NEAR(h.Quantile(0.5), 500 * kUs, 1 * kUs + 1e-12);
  EXPECT_NEAR(h.Quantile(0.99), 990 * kUs, 1 * kUs + 1e-12);
  EXPECT_LE(h.Quantile(0.999), h.max_s());
}

TEST(LatencyHistogramTest, ExponentialSampleMatchesItsQuantiles) {
  const double mean_s = 20 * kUs;
  const int n = 200000;
  std::mt19937_64 rng(18);
  std::exponential_distribution<double> exponential(1.0 / mean_s);
  LatencyHistogram h(1 * kUs, 0.05);
  for (int i = 0; i < n; ++i) h.Add(exponential(rng));
  for (double p : {0.5, 0.99, 0.999}) {
    const double q = -std::log(1.0 - p) * mean_s;
    const double density = (1.0 - p) / mean_s;
    const double standard_error = std::sqrt(p * (1.0 - p) / n) / density;
    EXPECT_NEAR(h.Quantile(p), q, 1 * kUs + 5 * standard_error) << "p=" << p;
  }
  EXPECT_NEAR(h.mean_s(), mean_s, 5 * mean_s / std::sqrt(n));
}

TEST(LatencyHistogramTest, OverflowKeepsTheExactMaximum) {
  LatencyHistogram h(10 * kUs, 1e-3);
  h.Add(0.505e-3);  // mid-bin: [500, 510) µs
  h.Add(2e-3);
  h.Add(3.7e-3);
  h.Add(1e-3);  // exactly max_s: overflow
  EXPECT_EQ(h.count(), 4u);
  EXPECT_EQ(h.overflow(), 3u);
  EXPECT_EQ(h.max_s(), 3.7e-3);
  EXPECT_EQ(h.Quantile(1.0), 3.7e-3);
  EXPECT_EQ(h.Quantile(0.9), 3.7e-3);  // in the overflow bin: the maximum
  EXPECT_NEAR(h.Quantile(0.25), 0.51e-3, 1e-12);
  EXPECT_NEAR(h.mean_s(), (0.505e-3 + 2e-3 + 3.7e-3 + 1e-3) / 4, 1e-15);
}

TEST(LatencyHistogramTest, SummaryIsInMicrosecondsRoundedToTheNanosecond) {
  LatencyHistogram h(1 * kUs, 1e-3);
  for (double v : {123.4567891e-6, 10.0004e-6, 10.0006e-6}) h.Add(v);
  const TimingSummary s = Summarize(h);
  EXPECT_EQ(s.count, 3u);
  EXPECT_EQ(s.max_us, 123.457);
  EXPECT_EQ(s.p50_us, 11.0);      // rank 2: bin [10, 11) µs
  EXPECT_EQ(s.p999_us, 123.457);  // bin edge 124 µs, capped at the maximum
  EXPECT_NEAR(s.mean_us, (123.4567891 + 10.0004 + 10.0006) / 3, 0.5 * kNsInUs);
}

TEST(LatencyHistogramTest, NegativeCountsAsZeroAndNanAsOverflow) {
  LatencyHistogram h(1 * kUs, 1e-3);
  h.Add(-5e-6);
  EXPECT_EQ(h.bins()[0], 1u);
  EXPECT_EQ(h.max_s(), 0.0);
  h.Add(std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(h.count(), 2u);
  EXPECT_EQ(h.overflow(), 1u);
  EXPECT_EQ(h.max_s(), 0.0);
  EXPECT_EQ(h.mean_s(), 0.0);  // the NaN is not averaged
}

TEST(LatencyHistogramTest, EmptyIsNanAndBadArgumentsThrow) {
  LatencyHistogram h;
  EXPECT_TRUE(std::isnan(h.Quantile(0.5)));
  EXPECT_TRUE(std::isnan(h.mean_s()));
  const TimingSummary s = Summarize(h);
  EXPECT_EQ(s.count, 0u);
  EXPECT_TRUE(std::isnan(s.p99_us));
  EXPECT_TRUE(std::isnan(s.max_us));
  ExpectContains(InvalidArgumentMessage([&] { h.Quantile(1.5); }), "outside [0, 1]");
  ExpectContains(InvalidArgumentMessage([&] { h.Quantile(std::nan("")); }), "Quantile");
  ExpectContains(InvalidArgumentMessage([] { LatencyHistogram(0.0, 1.0); }), "0 < bin_s");
  ExpectContains(InvalidArgumentMessage([] { LatencyHistogram(1.0, 1.0); }), "bin_s < max_s");
  ExpectContains(InvalidArgumentMessage([] { LatencyHistogram(std::nan(""), 1.0); }),
                 "LatencyHistogram");
  ExpectContains(InvalidArgumentMessage([] { LatencyHistogram(1e-9, 1.0); }), "10^6");
  EXPECT_NO_THROW(LatencyHistogram(1e-6, 1.0));  // exactly 10^6 bins
}

TEST(CycleTimerTest, EndingOnTheNextDeadlineIsNotAnOverrunJustAfterIs) {
  const double period = 1e-3;
  CycleTimer timer(period);
  const double deadline = 10.0;
  const double next = deadline + period;
  timer.Woke(deadline, deadline + 20 * kUs);
  EXPECT_FALSE(timer.Finished(next));
  timer.Woke(next, next + 10 * kUs);
  EXPECT_TRUE(timer.Finished(std::nextafter(next + period, 1e9)));
  const CycleTimingReport r = timer.Report();
  EXPECT_EQ(r.cycles, 2u);
  EXPECT_EQ(r.overruns, 1u);
  EXPECT_DOUBLE_EQ(r.overrun_fraction, 0.5);
  EXPECT_EQ(r.period_s, period);
  EXPECT_EQ(r.wakeup_latency.count, 2u);
  // Summaries are rounded to the ns; times near 10 s carry ~2e-9 µs of rounding.
  EXPECT_NEAR(r.wakeup_latency.max_us, 20.0, kNsInUs);
  EXPECT_NEAR(r.cycle_duration.max_us, 990.0, kNsInUs);
}

TEST(CycleTimerTest, CountsConsecutiveOverruns) {
  const double period = 1e-3;
  CycleTimer timer(period);
  // on time, 3 overruns, on time, 2 overruns, on time
  const bool pattern[] = {false, true, true, true, false, true, true, false};
  std::uint64_t expected_streak = 0;
  for (int k = 0; k < 8; ++k) {
    const double deadline = k * period;
    timer.Woke(deadline, deadline + 5 * kUs);
    const double end = deadline + (pattern[k] ? 1.5 : 0.5) * period;
    EXPECT_EQ(timer.Finished(end), pattern[k]) << k;
    expected_streak = pattern[k] ? expected_streak + 1 : 0;
    EXPECT_EQ(timer.consecutive_overruns(), expected_streak) << k;
  }
  const CycleTimingReport r = timer.Report();
  EXPECT_EQ(r.overruns, 5u);
  EXPECT_EQ(r.max_consecutive_overruns, 3u);
  EXPECT_DOUBLE_EQ(r.overrun_fraction, 5.0 / 8.0);
  EXPECT_NEAR(r.wakeup_latency.p50_us, 5.0, 1.0 + kNsInUs);  // 1 µs bins
  EXPECT_NEAR(r.cycle_duration.max_us, 1495.0, kNsInUs);
  EXPECT_NEAR(r.cycle_duration.mean_us, (5 * 1495.0 + 3 * 495.0) / 8, kNsInUs);
}

TEST(CycleTimerTest, LongOutageLandsInOverflowWithExactMax) {
  CycleTimer timer(1e-3);
  timer.Woke(0.0, 0.2);  // woke 200 ms late: past the 50 ms histogram range
  EXPECT_TRUE(timer.Finished(0.2005));
  EXPECT_EQ(timer.wakeup_latency().overflow(), 1u);
  EXPECT_NEAR(timer.Report().wakeup_latency.max_us, 200000.0, kNsInUs);
}

TEST(CycleTimerTest, RejectsBadPeriods) {
  for (double period : {0.0, -1e-3, std::nan(""), std::numeric_limits<double>::infinity()}) {
    ExpectContains(InvalidArgumentMessage([&] { CycleTimer timer(period); }), "period_s");
  }
}

TEST(CycleTimingReportTest, JsonParsesWithTheDocumentedKeys) {
  const double period = 1e-3;
  CycleTimer timer(period);
  for (int k = 0; k < 100; ++k) {
    const double deadline = k * period;
    timer.Woke(deadline, deadline + (k % 10) * kUs);
    timer.Finished(deadline + (k == 50 ? 1.2 : 0.3) * period);
  }
  const CycleTimingReport r = timer.Report();
  const nlohmann::json j = nlohmann::json::parse(r.Json());
  EXPECT_EQ(j.at("period_s").get<double>(), period);
  EXPECT_EQ(j.at("cycles").get<std::uint64_t>(), 100u);
  EXPECT_EQ(j.at("overruns").get<std::uint64_t>(), 1u);
  EXPECT_EQ(j.at("overrun_fraction").get<double>(), 0.01);
  EXPECT_EQ(j.at("max_consecutive_overruns").get<std::uint64_t>(), 1u);
  for (const char* key : {"wakeup_latency_us", "cycle_duration_us"}) {
    const TimingSummary& s =
        std::string(key) == "wakeup_latency_us" ? r.wakeup_latency : r.cycle_duration;
    const nlohmann::json& h = j.at(key);
    EXPECT_EQ(h.size(), 6u) << key;
    EXPECT_EQ(h.at("count").get<std::uint64_t>(), 100u) << key;
    EXPECT_EQ(h.at("p50").get<double>(), s.p50_us) << key;  // shortest round-trip text
    EXPECT_EQ(h.at("p99").get<double>(), s.p99_us) << key;
    EXPECT_EQ(h.at("p999").get<double>(), s.p999_us) << key;
    EXPECT_EQ(h.at("max").get<double>(), s.max_us) << key;
    EXPECT_EQ(h.at("mean").get<double>(), s.mean_us) << key;
  }
  EXPECT_NEAR(j["wakeup_latency_us"]["max"].get<double>(), 9.0, kNsInUs);
  EXPECT_NEAR(j["cycle_duration_us"]["max"].get<double>(), 1200.0, kNsInUs);
  EXPECT_EQ(r.Json().back(), '}');
}

TEST(CycleTimingReportTest, EmptyReportHasNullQuantiles) {
  const nlohmann::json j = nlohmann::json::parse(CycleTimer(1e-3).Report().Json());
  EXPECT_EQ(j.at("cycles").get<std::uint64_t>(), 0u);
  EXPECT_EQ(j.at("overrun_fraction").get<double>(), 0.0);
  EXPECT_TRUE(j.at("wakeup_latency_us").at("p99").is_null());
  EXPECT_TRUE(j.at("cycle_duration_us").at("max").is_null());
  EXPECT_EQ(j.at("cycle_duration_us").at("count").get<std::uint64_t>(), 0u);
}

}  // namespace
}  // namespace echoservo::control
