#include "link/message_conversion.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <type_traits>

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
static_assert(state_constants::MODE_RETRACTING ==
              static_cast<std::uint8_t>(ServoMode::kRetracting));
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
static_assert(state_constants::FAULT_IMAGE_NOT_RESPONDING == fault::kImageNotResponding);
static_assert(state_constants::FAULT_DEADLINE_HOLD == fault::kDeadlineHold);
static_assert(state_constants::FAULT_DEADLINE_RETRACT == fault::kDeadlineRetract);
static_assert(command_constants::ACTION_ENABLE == static_cast<std::uint8_t>(ServoAction::kEnable));
static_assert(command_constants::ACTION_DISABLE ==
              static_cast<std::uint8_t>(ServoAction::kDisable));
static_assert(command_constants::ACTION_STOP == static_cast<std::uint8_t>(ServoAction::kStop));
static_assert(command_constants::ACTION_SET_STANDOFF ==
              static_cast<std::uint8_t>(ServoAction::kSetStandoff));
static_assert(command_constants::ACTION_ENABLE == kMinServoAction);
static_assert(command_constants::ACTION_SET_STANDOFF == kMaxServoAction);

// One field between the wire type and the plain sample, each way. Same types copy by
// assignment (vectors keep their capacity), enums and integers convert, and Eigen
// vectors go to and from the IDL's double[3].
struct ToWire {
  template <class Wire, class Plain>
  void operator()(Wire& wire, const Plain& plain) const {
    if constexpr (std::is_same_v<Wire, Plain>) {
      wire = plain;
    } else {
      wire = static_cast<Wire>(plain);
    }
  }
  void operator()(std::array<double, 3>& wire, const Eigen::Vector3d& plain) const {
    wire = {plain.x(), plain.y(), plain.z()};
  }
};

struct FromWire {
  template <class Wire, class Plain>
  void operator()(const Wire& wire, Plain& plain) const {
    if constexpr (std::is_same_v<Wire, Plain>) {
      plain = wire;
    } else {
      plain = static_cast<Plain>(wire);  // any uint8 for enums: validation checks the range
    }
  }
  void operator()(const std::array<double, 3>& wire, Eigen::Vector3d& plain) const {
    plain = {wire[0], wire[1], wire[2]};
  }
};

// The field lists, once for both directions: `m` and `s` are const on the source side.
template <class Message, class Sample, class Copy>
void TargetFields(Message& m, Sample& s, Copy copy) {
  copy(m.sequence_number(), s.sequence_number);
  copy(m.acquisition_time_s(), s.acquisition_time_s);
  copy(m.publication_time_s(), s.publication_time_s);
  copy(m.target_mm(), s.target_mm);
  copy(m.axis(), s.axis);
  copy(m.tip_mm(), s.tip_mm);
  copy(m.motion_t0_s(), s.motion.t0_s);
  copy(m.motion_phase0_rad(), s.motion.phase0_rad);
  copy(m.motion_frequency_hz(), s.motion.frequency_hz);
  copy(m.motion_offset_mm(), s.motion.offset_mm);
  copy(m.motion_drift_mm_s(), s.motion.drift_mm_s);
  copy(m.motion_cos_mm(), s.motion.cos_mm);
  copy(m.motion_sin_mm(), s.motion.sin_mm);
  copy(m.motion_valid_until_s(), s.motion.valid_until_s);
  copy(m.confidence(), s.confidence);
}

template <class Message, class Sample, class Copy>
void StateFields(Message& m, Sample& s, Copy copy) {
  copy(m.sequence_number(), s.sequence_number);
  copy(m.stamp_s(), s.stamp_s);
  copy(m.mode(), s.mode);
  copy(m.faults(), s.faults);
  copy(m.fault_count(), s.fault_count);
  copy(m.base_mm(), s.base_mm);
  copy(m.base_velocity_mm_s(), s.base_velocity_mm_s);
  copy(m.tip_estimate_mm(), s.tip_estimate_mm);
  copy(m.setpoint_mm(), s.setpoint_mm);
  copy(m.force_n(), s.force_n);
  copy(m.standoff_mm(), s.standoff_mm);
  copy(m.estimate_age_s(), s.estimate_age_s);
}

template <class Message, class Sample, class Copy>
void CommandFields(Message& m, Sample& s, Copy copy) {
  copy(m.sequence_number(), s.sequence_number);
  copy(m.stamp_s(), s.stamp_s);
  copy(m.action(), s.action);
  copy(m.standoff_mm(), s.standoff_mm);
}

}  // namespace

void ToMessage(const TargetEstimateSample& s, echoservo_msgs::msg::TargetEstimate& m) {
  const std::size_t harmonics = std::max(s.motion.cos_mm.size(), s.motion.sin_mm.size());
  if (harmonics > kMaxHarmonics) {
    throw std::invalid_argument("TargetEstimateSample.motion: " + std::to_string(harmonics) +
                                " harmonics, the link carries at most " +
                                std::to_string(kMaxHarmonics));
  }
  TargetFields(m, s, ToWire{});
}

void FromMessage(const echoservo_msgs::msg::TargetEstimate& m, TargetEstimateSample& s) {
  TargetFields(m, s, FromWire{});
}

void ToMessage(const CatheterStateSample& s, echoservo_msgs::msg::CatheterState& m) {
  StateFields(m, s, ToWire{});
}

void FromMessage(const echoservo_msgs::msg::CatheterState& m, CatheterStateSample& s) {
  StateFields(m, s, FromWire{});
}

void ToMessage(const ServoCommandSample& s, echoservo_msgs::msg::ServoCommand& m) {
  CommandFields(m, s, ToWire{});
}

void FromMessage(const echoservo_msgs::msg::ServoCommand& m, ServoCommandSample& s) {
  CommandFields(m, s, FromWire{});
}

}  // namespace echoservo::link
