#include "link/message_conversion.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "echoservo_msgs/msg/CatheterState.h"
#include "echoservo_msgs/msg/ServoCommand.h"
#include "echoservo_msgs/msg/TargetEstimate.h"

namespace echoservo::link {
namespace {

namespace state_constants = echoservo_msgs::msg::CatheterState_Constants;
namespace command_constants = echoservo_msgs::msg::ServoCommand_Constants;

// The plain enums and bits are the IDL constants: a change to either side fails here.
static_assert(echoservo_msgs::msg::TargetEstimate_Constants::MAX_HARMONICS == kMaxHarmonics);
static_assert(state_constants::MODE_IDLE == static_cast<std::uint8_t>(ServoMode::kIdle));
static_assert(state_constants::MODE_TRACKING == static_cast<std::uint8_t>(ServoMode::kTracking));
static_assert(state_constants::MODE_HOLDING == static_cast<std::uint8_t>(ServoMode::kHolding));
static_assert(state_constants::MODE_RETRACTING == static_cast<std::uint8_t>(ServoMode::kRetracting));
static_assert(state_constants::MODE_STOPPED == static_cast<std::uint8_t>(ServoMode::kStopped));
static_assert(state_constants::MODE_FAULT == static_cast<std::uint8_t>(ServoMode::kFault));
static_assert(state_constants::MODE_FAULT == kMaxServoMode);
static_assert(state_constants::FAULT_STALE_ESTIMATE == fault::kStaleEstimate);
static_assert(state_constants::FAULT_INVALID_ESTIMATE == fault::kInvalidEstimate);
static_assert(state_constants::FAULT_TRAVEL_LIMIT == fault::kTravelLimit);
static_assert(state_constants::FAULT_VELOCITY_LIMIT == fault::kVelocityLimit);
static_assert(state_constants::FAULT_FORCE_LIMIT == fault::kForceLimit);
static_assert(state_constants::FAULT_NON_FINITE == fault::kNonFinite);
static_assert(state_constants::FAULT_HARDWARE == fault::kHardware);
static_assert(state_constants::FAULT_TRACKER_LOST == fault::kTrackerLost);
static_assert(command_constants::ACTION_ENABLE == static_cast<std::uint8_t>(ServoAction::kEnable));
static_assert(command_constants::ACTION_DISABLE == static_cast<std::uint8_t>(ServoAction::kDisable));
static_assert(command_constants::ACTION_STOP == static_cast<std::uint8_t>(ServoAction::kStop));
static_assert(command_constants::ACTION_SET_STANDOFF == static_cast<std::uint8_t>(ServoAction::kSetStandoff));
static_assert(command_constants::ACTION_ENABLE == kMinServoAction);
static_assert(command_constants::ACTION_SET_STANDOFF == kMaxServoAction);

std::array<double, 3> ToArray(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d FromArray(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }

}  // namespace

void ToMessage(const TargetEstimateSample& s, echoservo_msgs::msg::TargetEstimate& m) {
  const estimation::FourierMotion& motion = s.motion;
  const std::size_t harmonics = std::max(motion.cos_mm.size(), motion.sin_mm.size());
  if (harmonics > kMaxHarmonics) {
    throw std::invalid_argument("TargetEstimateSample.motion: " + std::to_string(harmonics) +
                                " harmonics, the link carries at most " + std::to_string(kMaxHarmonics));
  }
  m.sequence_number(s.sequence_number);
  m.acquisition_time_s(s.acquisition_time_s);
  m.publication_time_s(s.publication_time_s);
  m.target_mm(ToArray(s.target_mm));
  m.axis(ToArray(s.axis));
  m.tip_mm(ToArray(s.tip_mm));
  m.motion_t0_s(motion.t0_s);
  m.motion_phase0_rad(motion.phase0_rad);
  m.motion_frequency_hz(motion.frequency_hz);
  m.motion_offset_mm(motion.offset_mm);
  m.motion_drift_mm_s(motion.drift_mm_s);
  m.motion_cos_mm() = motion.cos_mm;  // assignment keeps the message's capacity
  m.motion_sin_mm() = motion.sin_mm;
  m.motion_valid_until_s(motion.valid_until_s);
  m.confidence(s.confidence);
}

void FromMessage(const echoservo_msgs::msg::TargetEstimate& m, TargetEstimateSample& s) {
  estimation::FourierMotion& motion = s.motion;
  s.sequence_number = m.sequence_number();
  s.acquisition_time_s = m.acquisition_time_s();
  s.publication_time_s = m.publication_time_s();
  s.target_mm = FromArray(m.target_mm());
  s.axis = FromArray(m.axis());
  s.tip_mm = FromArray(m.tip_mm());
  motion.t0_s = m.motion_t0_s();
  motion.phase0_rad = m.motion_phase0_rad();
  motion.frequency_hz = m.motion_frequency_hz();
  motion.offset_mm = m.motion_offset_mm();
  motion.drift_mm_s = m.motion_drift_mm_s();
  motion.cos_mm = m.motion_cos_mm();
  motion.sin_mm = m.motion_sin_mm();
  motion.valid_until_s = m.motion_valid_until_s();
  s.confidence = m.confidence();
}

void ToMessage(const CatheterStateSample& s, echoservo_msgs::msg::CatheterState& m) {
  m.sequence_number(s.sequence_number);
  m.stamp_s(s.stamp_s);
  m.mode(static_cast<std::uint8_t>(s.mode));
  m.faults(s.faults);
  m.fault_count(s.fault_count);
  m.base_mm(s.base_mm);
  m.base_velocity_mm_s(s.base_velocity_mm_s);
  m.tip_estimate_mm(s.tip_estimate_mm);
  m.setpoint_mm(s.setpoint_mm);
  m.force_n(s.force_n);
  m.standoff_mm(s.standoff_mm);
  m.estimate_age_s(s.estimate_age_s);
}

void FromMessage(const echoservo_msgs::msg::CatheterState& m, CatheterStateSample& s) {
  s.sequence_number = m.sequence_number();
  s.stamp_s = m.stamp_s();
  s.mode = static_cast<ServoMode>(m.mode());  // any uint8; validation checks the range
  s.faults = m.faults();
  s.fault_count = m.fault_count();
  s.base_mm = m.base_mm();
  s.base_velocity_mm_s = m.base_velocity_mm_s();
  s.tip_estimate_mm = m.tip_estimate_mm();
  s.setpoint_mm = m.setpoint_mm();
  s.force_n = m.force_n();
  s.standoff_mm = m.standoff_mm();
  s.estimate_age_s = m.estimate_age_s();
}

void ToMessage(const ServoCommandSample& s, echoservo_msgs::msg::ServoCommand& m) {
  m.sequence_number(s.sequence_number);
  m.stamp_s(s.stamp_s);
  m.action(static_cast<std::uint8_t>(s.action));
  m.standoff_mm(s.standoff_mm);
}

void FromMessage(const echoservo_msgs::msg::ServoCommand& m, ServoCommandSample& s) {
  s.sequence_number = m.sequence_number();
  s.stamp_s = m.stamp_s();
  s.action = static_cast<ServoAction>(m.action());  // any uint8; validation checks the range
  s.standoff_mm = m.standoff_mm();
}

}  // namespace echoservo::link
