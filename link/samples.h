// The samples the DDS link carries, as plain C++ (no Fast DDS types): the tracker's
// target estimate, the servo's catheter state and the operator's servo commands, with
// their ROS 2 topic and type names.
//
// Frames and units: positions in mm in the image (ultrasound volume) frame; `axis` is a
// unit vector; the motion model and the catheter state's positions are coordinates along
// the catheter axis in mm (the tracker's convention: s = axis · p, image frame); force in
// N; every time in s on the shared clock of link/clock.h. The IDL in
// msg/echoservo_msgs/msg mirrors these structs field by field (docs/dds.md).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "control/fault_bits.h"
#include "estimation/fourier_motion.h"

namespace echoservo::link {

// The bound of the IDL's harmonic sequences (TargetEstimate_Constants::MAX_HARMONICS).
inline constexpr std::size_t kMaxHarmonics = 16;

// ROS 2 names: topics carry the "rt/" prefix of ROS 2 topics, types are registered by
// fastddsgen -typeros2 as <package>::msg::dds_::<Type>_.
inline constexpr std::string_view kTargetTopic = "rt/echoservo/target_estimate";
inline constexpr std::string_view kStateTopic = "rt/echoservo/catheter_state";
inline constexpr std::string_view kCommandTopic = "rt/echoservo/servo_command";
inline constexpr std::string_view kTargetType = "echoservo_msgs::msg::dds_::TargetEstimate_";
inline constexpr std::string_view kStateType = "echoservo_msgs::msg::dds_::CatheterState_";
inline constexpr std::string_view kCommandType = "echoservo_msgs::msg::dds_::ServoCommand_";

struct TargetEstimateSample {
  std::uint64_t sequence_number = 0;  // the tracker's frame counter
  double acquisition_time_s = 0.0;    // volume acquisition
  double publication_time_s = 0.0;    // when the tracker published it
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit, towards the tip
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  // The predicted target coordinate along `axis`, valid until motion.valid_until_s
  // (finite on the link), at most kMaxHarmonics harmonics.
  estimation::FourierMotion motion;
  double confidence = 0.0;  // 0..1

  bool operator==(const TargetEstimateSample&) const = default;
};

// Values of CatheterState_Constants::MODE_*.
enum class ServoMode : std::uint8_t {
  kIdle = 0,
  kTracking = 1,
  kHolding = 2,     // the estimate went stale: holding position
  kRetracting = 3,  // still stale after the hold time: retracting
  kStopped = 4,
  kFault = 5,
};
inline constexpr std::uint8_t kMaxServoMode = 5;
std::string_view ToString(ServoMode m);

// Bits of CatheterStateSample::faults (CatheterState_Constants::FAULT_*): the servo's one
// fault-bit set (control/fault_bits.h).
namespace fault = control::fault;

struct CatheterStateSample {
  std::uint64_t sequence_number = 0;
  double stamp_s = 0.0;  // publication
  ServoMode mode = ServoMode::kIdle;
  std::uint32_t faults = 0;       // active fault:: bits
  std::uint64_t fault_count = 0;  // faults raised since start
  double base_mm = 0.0;
  double base_velocity_mm_s = 0.0;
  double tip_estimate_mm = 0.0;  // along the axis
  double setpoint_mm = 0.0;      // tip setpoint: target − standoff, along the axis
  double force_n = 0.0;
  double standoff_mm = 0.0;
  double estimate_age_s = 0.0;  // now − acquisition of the estimate in use

  bool operator==(const CatheterStateSample&) const = default;
};

// Values of ServoCommand_Constants::ACTION_*.
enum class ServoAction : std::uint8_t {
  kEnable = 1,       // track at standoff_mm
  kDisable = 2,      // hold, then idle
  kStop = 3,         // stop now (within one servo cycle)
  kSetStandoff = 4,  // change the standoff while tracking
};
inline constexpr std::uint8_t kMinServoAction = 1;
inline constexpr std::uint8_t kMaxServoAction = 4;
std::string_view ToString(ServoAction a);

struct ServoCommandSample {
  std::uint64_t sequence_number = 0;
  double stamp_s = 0.0;  // when issued
  ServoAction action = ServoAction::kStop;
  double standoff_mm = 0.0;  // for kEnable and kSetStandoff

  bool operator==(const ServoCommandSample&) const = default;
};

}  // namespace echoservo::link
