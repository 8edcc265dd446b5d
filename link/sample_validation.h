// Validation of samples received over the DDS link (pure C++, no DDS): a sample with a
// NaN/inf anywhere, a value outside its sane range, a timestamp in the future or older
// than the staleness limit, or a publication before its acquisition is rejected, and
// every rejection is counted by reason. Checks never throw on a bad sample; the
// subscriber keeps serving.
//
// Times in s on the shared clock (link/clock.h); `now_s` is the receiver's clock at
// reception. Across two hosts the clocks must be synchronised (PTP/NTP) to well under
// max_future_s and the max_*_age_s limits, or those limits relaxed.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

#include "link/samples.h"

namespace echoservo::link {

enum class Rejection : int {
  kNonFinite = 0,    // NaN or ±inf in any field
  kOutOfRange,       // a value outside its sane range (positions, frequency, ...)
  kBadMotionModel,   // harmonic count over the bound or cos/sin sizes that differ
  kFutureTimestamp,  // a timestamp later than now + max_future_s
  kStaleTimestamp,   // acquisition (or stamp) older than the max age
  kPublishedBeforeAcquired,
  kCount
};
std::string_view ToString(Rejection r);

struct ValidationLimits {
  double max_abs_position_mm = 1000.0;  // target, tip, motion terms, base, setpoints
  double max_abs_velocity_mm_s = 10000.0;
  double min_frequency_hz = 0.3;  // heart rate 18..300 bpm
  double max_frequency_hz = 5.0;
  std::size_t max_harmonics = kMaxHarmonics;
  double axis_norm_tolerance = 1e-3;  // | |axis| − 1 |
  double max_horizon_s = 10.0;        // motion valid_until − acquisition
  double max_abs_force_n = 100.0;
  double min_standoff_mm = 0.0;
  double max_standoff_mm = 30.0;
  double max_estimate_age_s = 3600.0;  // CatheterState::estimate_age_s
  double max_future_s = 0.05;          // clock offset and jitter tolerated
  double max_target_age_s = 0.5;       // now − acquisition of a target estimate
  double max_state_age_s = 1.0;        // now − stamp of a catheter state
  double max_command_age_s = 1.0;      // now − stamp of a command (no late old ENABLE)
  // Throws std::invalid_argument naming the field for a non-finite, negative or
  // inverted limit.
  void Validate() const;
};

// The first reason `s` is rejected for, or nothing when it is acceptable at `now_s`.
std::optional<Rejection> Check(const TargetEstimateSample& s, double now_s,
                               const ValidationLimits& l);
std::optional<Rejection> Check(const CatheterStateSample& s, double now_s,
                               const ValidationLimits& l);
std::optional<Rejection> Check(const ServoCommandSample& s, double now_s,
                               const ValidationLimits& l);

struct RejectionCounters {
  std::uint64_t accepted = 0;
  std::array<std::uint64_t, static_cast<int>(Rejection::kCount)> rejected{};

  std::uint64_t count(Rejection r) const { return rejected[static_cast<int>(r)]; }
  std::uint64_t total_rejected() const;
};

// Check() plus counting: Accept() returns whether `s` passed and counts the outcome.
class SampleValidator {
 public:
  explicit SampleValidator(ValidationLimits limits = {});  // validates the limits

  template <class Sample>
  bool Accept(const Sample& s, double now_s) {
    const std::optional<Rejection> r = Check(s, now_s, limits_);
    if (r) {
      ++counters_.rejected[static_cast<int>(*r)];
      return false;
    }
    ++counters_.accepted;
    return true;
  }
  const RejectionCounters& counters() const { return counters_; }
  const ValidationLimits& limits() const { return limits_; }

 private:
  ValidationLimits limits_;
  RejectionCounters counters_;
};

}  // namespace echoservo::link
