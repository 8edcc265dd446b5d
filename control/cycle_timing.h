// Timing of a periodic real-time loop: for every cycle the wake-up latency (how long after
// its deadline the thread ran) and the cycle's duration (wake-up to the end of its work),
// each into a fixed-bin histogram, and the overruns (cycles whose work ended after the next
// cycle's deadline). Nothing allocates after construction, so the loop can record every
// cycle. Times in s on one monotonic clock (std::chrono::steady_clock in the drivers);
// summaries in µs, as cyclictest reports them.
// Details: docs/control.md "Real-time execution".
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace echoservo::control {

// Counts of values in bins of `bin_s` from 0 to `max_s`; values at or past max_s go to an
// overflow bin (and still set max). Negative values count as 0; a NaN (no time) counts in
// the overflow bin without changing max or mean.
class LatencyHistogram {
 public:
  // Throws std::invalid_argument unless 0 < bin_s < max_s and max_s / bin_s ≤ 10^6.
  explicit LatencyHistogram(double bin_s = 1e-6, double max_s = 0.05);
  void Add(double value_s);
  std::uint64_t count() const { return count_; }
  std::uint64_t overflow() const { return overflow_; }
  double max_s() const { return max_s_seen_; }
  double mean_s() const;  // NaN when empty
  // The upper edge of the bin holding the p-quantile (p in [0, 1], else
  // std::invalid_argument), never more than max_s(); the exact maximum for p = 1 and for
  // quantiles in the overflow bin; NaN when empty.
  double Quantile(double p) const;
  double bin_s() const { return bin_s_; }
  const std::vector<std::uint64_t>& bins() const { return bins_; }

 private:
  double bin_s_, range_s_;
  std::vector<std::uint64_t> bins_;
  std::uint64_t count_ = 0, overflow_ = 0, nan_ = 0;
  double sum_s_ = 0.0, max_s_seen_ = 0.0;
};

// Quantiles, max and mean in µs of a histogram, rounded to the ns; all NaN (null in JSON)
// when it is empty.
struct TimingSummary {
  std::uint64_t count = 0;
  double p50_us = 0.0, p99_us = 0.0, p999_us = 0.0, max_us = 0.0, mean_us = 0.0;
};
TimingSummary Summarize(const LatencyHistogram& h);

struct CycleTimingReport {
  double period_s = 0.0;
  std::uint64_t cycles = 0;
  std::uint64_t overruns = 0;  // work ended after the next cycle's deadline
  double overrun_fraction = 0.0;
  std::uint64_t max_consecutive_overruns = 0;
  TimingSummary wakeup_latency;  // woke − deadline
  TimingSummary cycle_duration;  // end of work − woke
  // {"period_s":…, "cycles":…, "overruns":…, "overrun_fraction":…,
  //  "max_consecutive_overruns":…, "wakeup_latency_us": {"p50":…, "p99":…, "p999":…,
  //  "max":…, "mean":…, "count":…}, "cycle_duration_us": {…}} — no trailing newline.
  std::string Json() const;
};

// Histograms of a CycleTimer: 1 µs bins up to max(50 ms, 20 periods) (coarser bins past
// 10^6 of them); longer times land in the overflow bin and still set max.
class CycleTimer {
 public:
  // Throws std::invalid_argument unless period_s is finite and > 0.
  explicit CycleTimer(double period_s);
  // The cycle that should have started at `deadline_s` started at `woke_s`.
  void Woke(double deadline_s, double woke_s);
  // Its work ended at `end_s`; true when that is after the next deadline (an overrun).
  // Asserted: Woke was called for this cycle.
  bool Finished(double end_s);
  std::uint64_t consecutive_overruns() const { return consecutive_; }
  const LatencyHistogram& wakeup_latency() const { return wakeup_; }
  const LatencyHistogram& cycle_duration() const { return duration_; }
  CycleTimingReport Report() const;

 private:
  double period_s_;
  LatencyHistogram wakeup_, duration_;
  double deadline_s_ = 0.0, woke_s_ = 0.0;
  bool open_ = false;
  std::uint64_t cycles_ = 0, overruns_ = 0, consecutive_ = 0, max_consecutive_ = 0;
};

}  // namespace echoservo::control
