// The regular sampling the autoregressive predictors (estimation/ar_predictor.h,
// estimation/ls_ar_predictor.h) rest on: their lags are sample counts, so they need a nominal
// interval and must know when an interval breaks it.
//
// In: measurement times (s) and positions (mm), one at a time. The nominal interval is the
// median of the first kRateIntervals intervals. After that an interval within [0.4, 1.6] × the
// nominal one is the next sample; one of 2–4 nominal intervals (±0.3) is 1–3 dropped samples,
// which the caller fills by linear interpolation (FillDropped); anything else breaks the
// history (a gap or an irregular interval: the lags no longer mean the same delays).
// Errors: Accept throws std::invalid_argument, naming the owner, for a non-finite input or a
// time not after the previous one (nothing is changed then).
#pragma once

#include <cstddef>
#include <deque>
#include <string>
#include <vector>

namespace echoservo::estimation {

class SampleGrid {
 public:
  // Intervals whose median sets the nominal one.
  static constexpr std::size_t kRateIntervals = 8;

  enum class Step {
    kLearning,  // the nominal interval is not known yet
    kLearned,   // this interval completed it: the caller configures itself
    kNext,      // the next sample on the grid
    kDropped,   // 1–3 samples are missing before this one (dropped())
    kBroken,    // a gap or an irregular interval: the history no longer applies
  };

  // `owner` names the caller in error messages.
  explicit SampleGrid(std::string owner) : owner_(std::move(owner)) {}

  // Validates and classifies a new measurement (see the file comment).
  Step Accept(double t_s, double position_mm);

  double dt_s() const { return dt_s_; }  // nominal interval; 0 until learned
  double last_t_s() const { return t_s_; }
  long dropped() const { return dropped_; }  // after kDropped: the samples missing

 private:
  std::string owner_;
  std::vector<double> intervals_;
  double dt_s_ = 0.0;
  double t_s_ = 0.0;
  bool any_ = false;
  long dropped_ = 0;
};

// After SampleGrid::Step::kDropped: the `missing` samples between history.back() and `z`,
// linearly interpolated, each appended (history kept to `keep`) and handed to `learn`.
template <typename Learn>
void FillDropped(std::deque<double>& history, double z, long missing, std::size_t keep,
                 Learn&& learn) {
  const double from = history.back();
  for (long i = 1; i <= missing; ++i) {
    history.push_back(from +
                      (z - from) * static_cast<double>(i) / static_cast<double>(missing + 1));
    while (history.size() > keep) history.pop_front();
    learn();
  }
}

// What AppendOnGrid did to a history over its life.
struct GridCounters {
  std::size_t filled = 0;          // intervals of 2–4 nominal ones filled by interpolation
  std::size_t history_resets = 0;  // gaps or irregular intervals (the history restarted)
};

// One measurement into a predictor's history on the grid: while the nominal interval is
// learned, the newest kRateIntervals + 1 samples are kept and false is returned (the caller
// holds `z`); when it is learned, `configure()` runs (it may change `keep`); dropped samples
// are filled (each handed to `learn()`), a gap or an irregular interval clears the history;
// then `z` is appended, the history kept to `keep`, `learn()` called, and true returned.
// Throws as SampleGrid::Accept (nothing changed then).
template <typename Configure, typename Learn>
bool AppendOnGrid(SampleGrid& grid, double t_s, double z, std::deque<double>& history,
                  const std::size_t& keep, GridCounters& counters, Configure&& configure,
                  Learn&& learn) {
  switch (grid.Accept(t_s, z)) {
    case SampleGrid::Step::kLearning:
      history.push_back(z);
      while (history.size() > SampleGrid::kRateIntervals + 1) history.pop_front();
      return false;
    case SampleGrid::Step::kLearned:
      configure();
      break;
    case SampleGrid::Step::kNext:
      break;
    case SampleGrid::Step::kDropped:
      if (!history.empty()) {
        FillDropped(history, z, grid.dropped(), keep, learn);
        ++counters.filled;
        break;
      }
      [[fallthrough]];
    case SampleGrid::Step::kBroken:
      history.clear();
      ++counters.history_resets;
      break;
  }
  history.push_back(z);
  while (history.size() > keep) history.pop_front();
  learn();
  return true;
}

// `y` clamped to the newest `span` samples' range ± `margin_fraction` of it; the newest sample
// when `y` is not finite.
double ClampToRecentRange(const std::deque<double>& history, std::size_t span,
                          double margin_fraction, double y);

// A direct predictor's output between the newest measurement (at newest_t_s) and its
// horizon: linear from the newest value to the prediction, held past the horizon.
double TowardsHorizon(double newest_mm, double predicted_mm, double newest_t_s, double horizon_s,
                      double t_s);

}  // namespace echoservo::estimation
