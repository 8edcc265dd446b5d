#include "report/scored_window.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

namespace echoservo::report {
namespace {

std::string WindowFixed(double v, int digits) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

}  // namespace

double SettleTimeS(std::optional<double> heart_rate_hz) {
  if (!heart_rate_hz || !(*heart_rate_hz > 0.0) || !std::isfinite(*heart_rate_hz))
    return kMinSettleS;
  return std::max(kSettleBeats / *heart_rate_hz, kMinSettleS);
}

ScoredWindow WindowAfterFollowing(double following_s, std::optional<double> heart_rate_hz) {
  ScoredWindow w;
  w.following_s = following_s;
  w.settle_s = SettleTimeS(heart_rate_hz);
  w.from_s = following_s + w.settle_s;
  const bool rate = heart_rate_hz && *heart_rate_hz > 0.0 && std::isfinite(*heart_rate_hz);
  w.reason =
      "servo began following at " + WindowFixed(following_s, 2) + " s + settling " +
      WindowFixed(w.settle_s, 2) + " s (" +
      (rate ? WindowFixed(kSettleBeats, 0) + " beats at " + WindowFixed(60.0 * *heart_rate_hz, 1) +
                  " bpm, at least " + WindowFixed(kMinSettleS, 1) + " s"
            : "no heart rate stated: " + WindowFixed(kMinSettleS, 1) + " s") +
      ")";
  return w;
}

ScoredWindow GivenWindow(double from_s, std::string reason) {
  ScoredWindow w;
  w.from_s = from_s;
  w.reason = std::move(reason);
  return w;
}

ScoredWindow WholeRun(std::string reason) {
  ScoredWindow w;
  w.reason = std::move(reason);
  return w;
}

std::string Describe(const ScoredWindow& w) {
  if (!std::isfinite(w.from_s)) return w.reason;
  return "from " + WindowFixed(w.from_s, 2) + " s: " + w.reason;
}

}  // namespace echoservo::report
