// The servo's fault bits: one set, used by the follower (control/target_follower.h), the
// servo node (live/servo_node.h) and the link (link/samples.h: CatheterStateSample::faults,
// CatheterState_Constants::FAULT_* in msg/echoservo_msgs/msg/CatheterState.idl). Bits 0–10
// go on the state topic; the follower's latched conditions that are modes rather than faults
// (a STOP, a finished retraction) sit above them and never leave the servo (kAll masks them).
#pragma once

#include <cstdint>

namespace echoservo::control::fault {

inline constexpr std::uint32_t kStaleEstimate = 1u << 0;    // the estimate in use is too old
inline constexpr std::uint32_t kInvalidEstimate = 1u << 1;  // an estimate was rejected
inline constexpr std::uint32_t kTravelLimit = 1u << 2;      // the reference was clamped to travel
inline constexpr std::uint32_t kVelocityLimit = 1u << 3;
inline constexpr std::uint32_t kForceLimit = 1u << 4;
inline constexpr std::uint32_t kNonFinite = 1u << 5;  // a non-finite command or reading
inline constexpr std::uint32_t kHardware = 1u << 6;   // the hardware reported a fault
inline constexpr std::uint32_t kTrackerLost = 1u << 7;
// The imaged tip does not follow the catheter's (response check): latched until ENABLE.
inline constexpr std::uint32_t kImageNotResponding = 1u << 8;
// The servo loop missed its deadlines (control/deadline_watchdog.h): K overruns in a row,
// holding until cleared; no cycle on time for the retraction time, retracting (latched until
// ENABLE).
inline constexpr std::uint32_t kDeadlineHold = 1u << 9;
inline constexpr std::uint32_t kDeadlineRetract = 1u << 10;
// Every bit that goes on the link.
inline constexpr std::uint32_t kAll = (1u << 11) - 1;

// The follower's latched modes (not faults, never on the link).
inline constexpr std::uint32_t kStopRequested = 1u << 16;
inline constexpr std::uint32_t kRetracted = 1u << 17;

}  // namespace echoservo::control::fault
