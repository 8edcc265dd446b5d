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

// A direct predictor's output between the newest measurement (at newest_t_s) and its
// horizon: linear from the newest value to the prediction, held past the horizon.
double TowardsHorizon(double newest_mm, double predicted_mm, double newest_t_s, double horizon_s,
                      double t_s);

}  // namespace echoservo::estimation
