#include "link/sample_validation.h"

#include <cmath>
#include <initializer_list>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

namespace echoservo::link {
namespace {

bool AllFinite(std::initializer_list<double> values) {
  for (double v : values) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

bool AllFinite(const std::vector<double>& values) {
  for (double v : values) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

bool AllFinite(const Eigen::Vector3d& v) { return v.allFinite(); }

bool Within(double v, double bound) { return std::abs(v) <= bound; }

bool Within(const std::vector<double>& values, double bound) {
  for (double v : values) {
    if (!Within(v, bound)) return false;
  }
  return true;
}

bool Within(const Eigen::Vector3d& v, double bound) { return v.cwiseAbs().maxCoeff() <= bound; }

// The time checks shared by all samples: `t_s` neither in the future beyond the
// tolerance nor older than `max_age_s`.
std::optional<Rejection> CheckTime(double t_s, double now_s, double max_age_s,
                                   const ValidationLimits& l) {
  if (t_s > now_s + l.max_future_s) return Rejection::kFutureTimestamp;
  if (now_s - t_s > max_age_s) return Rejection::kStaleTimestamp;
  return std::nullopt;
}

void RequireLimit(bool ok, const char* field) {
  if (!ok) throw std::invalid_argument(std::string("ValidationLimits.") + field + " is invalid");
}

}  // namespace

std::string_view ToString(Rejection r) {
  switch (r) {
    case Rejection::kNonFinite:
      return "non_finite";
    case Rejection::kOutOfRange:
      return "out_of_range";
    case Rejection::kBadMotionModel:
      return "bad_motion_model";
    case Rejection::kFutureTimestamp:
      return "future_timestamp";
    case Rejection::kStaleTimestamp:
      return "stale_timestamp";
    case Rejection::kPublishedBeforeAcquired:
      return "published_before_acquired";
    case Rejection::kCount:
      break;
  }
  return "unknown";
}

void ValidationLimits::Validate() const {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  const auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  RequireLimit(positive(max_abs_position_mm), "max_abs_position_mm");
  RequireLimit(positive(max_abs_velocity_mm_s), "max_abs_velocity_mm_s");
  RequireLimit(positive(min_frequency_hz), "min_frequency_hz");
  RequireLimit(positive(max_frequency_hz) && max_frequency_hz >= min_frequency_hz,
               "max_frequency_hz");
  RequireLimit(max_harmonics <= kMaxHarmonics, "max_harmonics");
  RequireLimit(positive(axis_norm_tolerance), "axis_norm_tolerance");
  RequireLimit(positive(max_horizon_s), "max_horizon_s");
  RequireLimit(positive(max_abs_force_n), "max_abs_force_n");
  RequireLimit(non_negative(min_standoff_mm), "min_standoff_mm");
  RequireLimit(positive(max_standoff_mm) && max_standoff_mm >= min_standoff_mm, "max_standoff_mm");
  RequireLimit(positive(max_estimate_age_s), "max_estimate_age_s");
  RequireLimit(non_negative(max_future_s), "max_future_s");
  RequireLimit(positive(max_target_age_s), "max_target_age_s");
  RequireLimit(positive(max_state_age_s), "max_state_age_s");
  RequireLimit(positive(max_command_age_s), "max_command_age_s");
}

std::optional<Rejection> Check(const TargetEstimateSample& s, double now_s,
                               const ValidationLimits& l) {
  const estimation::FourierMotion& m = s.motion;
  if (!AllFinite({s.acquisition_time_s, s.publication_time_s, s.confidence, m.t0_s, m.phase0_rad,
                  m.frequency_hz, m.offset_mm, m.drift_mm_s, m.valid_until_s}) ||
      !AllFinite(s.target_mm) || !AllFinite(s.axis) || !AllFinite(s.tip_mm) ||
      !AllFinite(m.cos_mm) || !AllFinite(m.sin_mm)) {
    return Rejection::kNonFinite;
  }
  if (m.cos_mm.size() != m.sin_mm.size() || m.cos_mm.size() > l.max_harmonics) {
    return Rejection::kBadMotionModel;
  }
  const bool in_range =
      Within(s.target_mm, l.max_abs_position_mm) && Within(s.tip_mm, l.max_abs_position_mm) &&
      std::abs(s.axis.norm() - 1.0) <= l.axis_norm_tolerance && s.confidence >= 0.0 &&
      s.confidence <= 1.0 && m.frequency_hz >= l.min_frequency_hz &&
      m.frequency_hz <= l.max_frequency_hz && Within(m.offset_mm, l.max_abs_position_mm) &&
      Within(m.drift_mm_s, l.max_abs_velocity_mm_s) && Within(m.cos_mm, l.max_abs_position_mm) &&
      Within(m.sin_mm, l.max_abs_position_mm) && m.valid_until_s >= s.acquisition_time_s &&
      m.valid_until_s - s.acquisition_time_s <= l.max_horizon_s &&
      std::abs(m.t0_s - s.acquisition_time_s) <= l.max_horizon_s;
  if (!in_range) return Rejection::kOutOfRange;
  if (s.publication_time_s < s.acquisition_time_s) return Rejection::kPublishedBeforeAcquired;
  if (s.publication_time_s > now_s + l.max_future_s) return Rejection::kFutureTimestamp;
  return CheckTime(s.acquisition_time_s, now_s, l.max_target_age_s, l);
}

std::optional<Rejection> Check(const CatheterStateSample& s, double now_s,
                               const ValidationLimits& l) {
  if (!AllFinite({s.stamp_s, s.base_mm, s.base_velocity_mm_s, s.tip_estimate_mm, s.setpoint_mm,
                  s.force_n, s.standoff_mm, s.estimate_age_s})) {
    return Rejection::kNonFinite;
  }
  const bool in_range =
      static_cast<std::uint8_t>(s.mode) <= kMaxServoMode && (s.faults & ~fault::kAll) == 0 &&
      Within(s.base_mm, l.max_abs_position_mm) &&
      Within(s.base_velocity_mm_s, l.max_abs_velocity_mm_s) &&
      Within(s.tip_estimate_mm, l.max_abs_position_mm) &&
      Within(s.setpoint_mm, l.max_abs_position_mm) && Within(s.force_n, l.max_abs_force_n) &&
      s.standoff_mm >= l.min_standoff_mm && s.standoff_mm <= l.max_standoff_mm &&
      s.estimate_age_s >= 0.0 && s.estimate_age_s <= l.max_estimate_age_s;
  if (!in_range) return Rejection::kOutOfRange;
  return CheckTime(s.stamp_s, now_s, l.max_state_age_s, l);
}

std::optional<Rejection> Check(const ServoCommandSample& s, double now_s,
                               const ValidationLimits& l) {
  if (!AllFinite({s.stamp_s, s.standoff_mm})) return Rejection::kNonFinite;
  const auto action = static_cast<std::uint8_t>(s.action);
  const bool uses_standoff =
      s.action == ServoAction::kEnable || s.action == ServoAction::kSetStandoff;
  const bool in_range = action >= kMinServoAction && action <= kMaxServoAction &&
                        (!uses_standoff || (s.standoff_mm >= l.min_standoff_mm &&
                                            s.standoff_mm <= l.max_standoff_mm));
  if (!in_range) return Rejection::kOutOfRange;
  return CheckTime(s.stamp_s, now_s, l.max_command_age_s, l);
}

std::uint64_t RejectionCounters::total_rejected() const {
  return std::accumulate(rejected.begin(), rejected.end(), std::uint64_t{0});
}

SampleValidator::SampleValidator(ValidationLimits limits) : limits_(limits) { limits_.Validate(); }

}  // namespace echoservo::link
