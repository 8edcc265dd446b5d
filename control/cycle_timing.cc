// Fixed-bin latency histograms and per-cycle overrun accounting (control/cycle_timing.h).
// Add, Woke and Finished touch only preallocated members: no allocation, no lock.
#include "control/cycle_timing.h"

#include <algorithm>
#include <cassert>
#include <charconv>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <system_error>

namespace echoservo::control {
namespace {

constexpr double kTimingMaxBins = 1e6;
constexpr double kTimingNaN = std::numeric_limits<double>::quiet_NaN();

// Bins of CycleTimer's histograms: 1 µs, over at least 50 ms and 20 periods.
constexpr double kTimerBinS = 1e-6;
constexpr double kTimerMinRangeS = 0.05;
constexpr double kTimerRangePeriods = 20.0;

std::size_t TimingBinCount(double bin_s, double max_s) {
  if (!(std::isfinite(bin_s) && std::isfinite(max_s) && bin_s > 0.0 && bin_s < max_s)) {
    throw std::invalid_argument("LatencyHistogram: needs 0 < bin_s < max_s, finite (bin_s " +
                                std::to_string(bin_s) + ", max_s " + std::to_string(max_s) + ")");
  }
  const double bins = std::ceil(max_s / bin_s);
  if (bins > kTimingMaxBins) {
    throw std::invalid_argument("LatencyHistogram: max_s / bin_s = " + std::to_string(bins) +
                                " bins, at most 10^6 (bin_s " + std::to_string(bin_s) + ", max_s " +
                                std::to_string(max_s) + ")");
  }
  return static_cast<std::size_t>(bins);
}

double TimingValidPeriod(double period_s) {
  if (!(std::isfinite(period_s) && period_s > 0.0)) {
    throw std::invalid_argument("CycleTimer: period_s " + std::to_string(period_s) +
                                " must be finite and > 0");
  }
  return period_s;
}

double TimerRangeS(double period_s) {
  return std::max(kTimerMinRangeS, kTimerRangePeriods * period_s);
}

double TimerBinS(double period_s) {
  return std::max(kTimerBinS, TimerRangeS(period_s) / kTimingMaxBins);
}

// s → µs, rounded to the nanosecond (the clocks' resolution), so that a bin edge such as
// 229 µs reads 229 and not 228.99999999999997.
double TimingMicroseconds(double s) { return std::round(s * 1e9) / 1e3; }

// Shortest text that reads back as the same double; null for NaN and infinities (JSON).
void TimingAppendNumber(std::string& out, double value) {
  if (!std::isfinite(value)) {
    out += "null";
    return;
  }
  char buffer[32];
  const auto [end, error] = std::to_chars(buffer, buffer + sizeof buffer, value);
  assert(error == std::errc());
  (void)error;
  out.append(buffer, end);
}

void TimingAppendSummary(std::string& out, const TimingSummary& s) {
  out += "{\"p50\":";
  TimingAppendNumber(out, s.p50_us);
  out += ",\"p99\":";
  TimingAppendNumber(out, s.p99_us);
  out += ",\"p999\":";
  TimingAppendNumber(out, s.p999_us);
  out += ",\"max\":";
  TimingAppendNumber(out, s.max_us);
  out += ",\"mean\":";
  TimingAppendNumber(out, s.mean_us);
  out += ",\"count\":" + std::to_string(s.count) + "}";
}

}  // namespace

LatencyHistogram::LatencyHistogram(double bin_s, double max_s)
    : bin_s_(bin_s), range_s_(max_s), bins_(TimingBinCount(bin_s, max_s), 0) {}

void LatencyHistogram::Add(double value_s) {
  ++count_;
  if (std::isnan(value_s)) {  // no time: counted, but it says nothing about max or mean
    ++overflow_;
    ++nan_;
    return;
  }
  const double v = std::max(value_s, 0.0);
  sum_s_ += v;
  max_s_seen_ = std::max(max_s_seen_, v);
  if (v >= range_s_) {
    ++overflow_;
    return;
  }
  const auto index = static_cast<std::size_t>(v / bin_s_);
  if (index >= bins_.size()) {  // rounding just below range_s_
    ++overflow_;
    return;
  }
  ++bins_[index];
}

double LatencyHistogram::mean_s() const {
  const std::uint64_t timed = count_ - nan_;
  return timed == 0 ? kTimingNaN : sum_s_ / static_cast<double>(timed);
}

double LatencyHistogram::Quantile(double p) const {
  if (!(p >= 0.0 && p <= 1.0)) {
    throw std::invalid_argument("LatencyHistogram::Quantile: p = " + std::to_string(p) +
                                " is outside [0, 1]");
  }
  if (count_ == 0) return kTimingNaN;
  if (p == 1.0) return max_s_seen_;
  // The smallest value with at least ceil(p · count) values at or below it.
  const auto rank = std::max<std::uint64_t>(
      1, static_cast<std::uint64_t>(std::ceil(p * static_cast<double>(count_))));
  std::uint64_t cumulative = 0;
  for (std::size_t i = 0; i < bins_.size(); ++i) {
    cumulative += bins_[i];
    if (cumulative >= rank) {
      return std::min(static_cast<double>(i + 1) * bin_s_, max_s_seen_);
    }
  }
  return max_s_seen_;  // in the overflow bin
}

TimingSummary Summarize(const LatencyHistogram& h) {
  TimingSummary s;
  s.count = h.count();
  if (s.count == 0) {
    s.p50_us = s.p99_us = s.p999_us = s.max_us = s.mean_us = kTimingNaN;
    return s;
  }
  s.p50_us = TimingMicroseconds(h.Quantile(0.5));
  s.p99_us = TimingMicroseconds(h.Quantile(0.99));
  s.p999_us = TimingMicroseconds(h.Quantile(0.999));
  s.max_us = TimingMicroseconds(h.max_s());
  s.mean_us = TimingMicroseconds(h.mean_s());
  return s;
}

std::string CycleTimingReport::Json() const {
  std::string out = "{\"period_s\":";
  TimingAppendNumber(out, period_s);
  out += ",\"cycles\":" + std::to_string(cycles);
  out += ",\"overruns\":" + std::to_string(overruns);
  out += ",\"overrun_fraction\":";
  TimingAppendNumber(out, overrun_fraction);
  out += ",\"max_consecutive_overruns\":" + std::to_string(max_consecutive_overruns);
  out += ",\"wakeup_latency_us\":";
  TimingAppendSummary(out, wakeup_latency);
  out += ",\"cycle_duration_us\":";
  TimingAppendSummary(out, cycle_duration);
  out += "}";
  return out;
}

CycleTimer::CycleTimer(double period_s)
    : period_s_(TimingValidPeriod(period_s)),
      wakeup_(TimerBinS(period_s_), TimerRangeS(period_s_)),
      duration_(TimerBinS(period_s_), TimerRangeS(period_s_)) {}

void CycleTimer::Woke(double deadline_s, double woke_s) {
  assert(!open_ && "CycleTimer::Woke: the previous cycle was not Finished");
  wakeup_.Add(woke_s - deadline_s);
  deadline_s_ = deadline_s;
  woke_s_ = woke_s;
  open_ = true;
}

bool CycleTimer::Finished(double end_s) {
  assert(open_ && "CycleTimer::Finished without Woke");
  if (!open_) return false;  // release build: a call out of order records nothing
  open_ = false;
  duration_.Add(end_s - woke_s_);
  ++cycles_;
  const bool overran = end_s > deadline_s_ + period_s_;
  if (overran) {
    ++overruns_;
    ++consecutive_;
    max_consecutive_ = std::max(max_consecutive_, consecutive_);
  } else {
    consecutive_ = 0;
  }
  return overran;
}

CycleTimingReport CycleTimer::Report() const {
  CycleTimingReport r;
  r.period_s = period_s_;
  r.cycles = cycles_;
  r.overruns = overruns_;
  r.overrun_fraction =
      cycles_ == 0 ? 0.0 : static_cast<double>(overruns_) / static_cast<double>(cycles_);
  r.max_consecutive_overruns = max_consecutive_;
  r.wakeup_latency = Summarize(wakeup_);
  r.cycle_duration = Summarize(duration_);
  return r;
}

}  // namespace echoservo::control
