#include "estimation/sample_grid.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace echoservo::estimation {
namespace {

constexpr double kIrregularHigh = 1.6;  // an interval beyond this × nominal breaks the grid
constexpr double kIrregularLow = 0.4;   // below this × nominal too
constexpr long kMaxDropped = 3;         // dropped samples the caller may fill
constexpr double kOnGrid = 0.3;         // a multiple of the nominal interval within this

}  // namespace

SampleGrid::Step SampleGrid::Accept(double t_s, double z) {
  if (!std::isfinite(t_s) || !std::isfinite(z)) {
    throw std::invalid_argument(owner_ + ": a measurement or its time is NaN or infinite");
  }
  if (any_ && !(t_s > t_s_)) {
    throw std::invalid_argument(owner_ + ": measurement times must be strictly increasing");
  }
  const bool first = !any_;
  const double dt = t_s - t_s_;
  any_ = true;
  t_s_ = t_s;
  if (first) return Step::kLearning;
  if (dt_s_ == 0.0) {
    intervals_.push_back(dt);
    if (intervals_.size() < kRateIntervals) return Step::kLearning;
    std::nth_element(intervals_.begin(),
                     intervals_.begin() + static_cast<std::ptrdiff_t>(intervals_.size() / 2),
                     intervals_.end());
    dt_s_ = intervals_[intervals_.size() / 2];
    return Step::kLearned;
  }
  if (dt <= kIrregularHigh * dt_s_ && dt >= kIrregularLow * dt_s_) return Step::kNext;
  const double steps = dt / dt_s_;
  const long k = std::lround(steps);
  if (k >= 2 && k <= kMaxDropped + 1 && std::abs(steps - static_cast<double>(k)) < kOnGrid) {
    dropped_ = k - 1;
    return Step::kDropped;
  }
  return Step::kBroken;
}

double ClampToRecentRange(const std::deque<double>& history, std::size_t span,
                          double margin_fraction, double y) {
  const double newest = history.back();
  if (!std::isfinite(y)) return newest;
  span = std::min(history.size(), span);
  const auto [lo, hi] =
      std::minmax_element(history.end() - static_cast<std::ptrdiff_t>(span), history.end());
  const double margin = margin_fraction * (*hi - *lo);
  return std::clamp(y, *lo - margin, *hi + margin);
}

double TowardsHorizon(double newest_mm, double predicted_mm, double newest_t_s, double horizon_s,
                      double t_s) {
  const double dt = t_s - newest_t_s;
  if (!(dt > 0.0) || horizon_s <= 0.0) return newest_mm;
  const double frac = std::min(1.0, dt / horizon_s);
  return newest_mm + frac * (predicted_mm - newest_mm);
}

}  // namespace echoservo::estimation
