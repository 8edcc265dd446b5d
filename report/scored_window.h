// The scored window of a closed-loop run: the one definition `echoservo demo` prints its
// tip-to-target RMS over and `echoservo report RUN` scores by default, so that the two give
// the same figure for the same run.
//
// The window opens when the servo began following (servo.csv's first row in the following
// mode; the demo notes the same row as it writes it) plus a settling time: the approach from
// rest to the target less the standoff and the predictor's first beats. On the demo (seed 1,
// 60 bpm, 12 s) the per-beat RMS after following began is 3.39, 0.79, 0.47, 0.39, 0.40,
// 0.40 mm: two beats settle it. So the settling time is kSettleBeats beats at the run's heart
// rate (run.json heart_rate_hz), and at least kMinSettleS (a fast heart does not shorten the
// approach); without a stated rate, kMinSettleS. A window given by the user (report --from,
// demo --metrics-start) replaces it. Units: s on the run's clock.
#pragma once

#include <limits>
#include <optional>
#include <string>

namespace echoservo::report {

inline constexpr double kSettleBeats = 2.0;
inline constexpr double kMinSettleS = 2.0;

struct ScoredWindow {
  // Scored from here on (−inf: the whole run).
  double from_s = -std::numeric_limits<double>::infinity();
  double following_s = std::numeric_limits<double>::quiet_NaN();  // NaN: given, or never
  double settle_s = 0.0;
  // Why: "servo began following at 2.35 s + settling 2.00 s (2 beats at 60.0 bpm)",
  // "--from", "whole run: no servo.csv".
  std::string reason;
};

// The settling time after following began (s): kSettleBeats beats, at least kMinSettleS.
double SettleTimeS(std::optional<double> heart_rate_hz);

// The window of a run whose servo began following at `following_s`.
ScoredWindow WindowAfterFollowing(double following_s, std::optional<double> heart_rate_hz);
// A window the user gave (`reason`: the flag).
ScoredWindow GivenWindow(double from_s, std::string reason);
// The whole run (`reason`: why no window applies).
ScoredWindow WholeRun(std::string reason);

// "from 4.35 s: servo began following at 2.35 s + settling 2.00 s (2 beats at 60.0 bpm)",
// or the reason alone for the whole run.
std::string Describe(const ScoredWindow& w);

}  // namespace echoservo::report
