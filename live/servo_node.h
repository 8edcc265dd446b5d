// The servo node of the live pipeline: the 1 kHz catheter control (control/servo_loop.h)
// following the tracker's predicted target at a standoff (control/target_follower.h), driven
// by the DDS link (link/dds_link.h): target estimates and operator commands in, the catheter
// state out at state_rate_hz. `echoservo servo` and `echoservo demo` drive the same node, on
// any hw::HardwareInterface.
//
// Each Cycle(t) also checks every limit on what was commanded (limit_violations: must stay
// 0); a non-finite base, tip or force reading stops the servo. The one place follower modes
// and faults map to link::ServoMode and link::fault bits. Units: mm, s, N; positions along
// the catheter axis; link stamps − link_offset_s = node clock.
// Errors: the constructor throws std::invalid_argument for bad options.
// Details: docs/live.md#the-servo-node-liveservo_nodeh
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>

#include "control/servo_loop.h"
#include "control/target_follower.h"
#include "link/dds_link.h"

namespace echoservo::live {

struct ServoNodeOptions {
  control::FollowerConfig follower;
  double state_rate_hz = 100.0;  // (0, 1000]
  // Enable at the first accepted estimate and again after a retraction (the demo and
  // tests); otherwise the servo waits for an ENABLE command.
  bool auto_enable = false;
  double link_offset_s = 0.0;  // link time − node time
  link::ValidationLimits limits;
  void Validate() const;  // throws std::invalid_argument naming the field
};

struct ServoNodeStats {
  std::uint64_t cycles = 0;
  std::uint64_t estimates_accepted = 0, estimates_rejected = 0;  // by the follower
  std::uint64_t commands_applied = 0, commands_rejected = 0;     // rejected: bad standoff
  std::uint64_t states_published = 0;
  std::uint64_t resumes = 0;           // auto_enable after a retraction
  std::uint64_t fault_events = 0;      // rising edges of fault bits
  std::uint64_t limit_violations = 0;  // commanded travel/velocity/force outside the limits
  // Every cycle a limit intervened: the follower's reference clamped to travel, and the
  // limiter's faults (travel clamp, non-finite, force clamp), each counted per cycle.
  std::uint64_t limit_interventions = 0;
  std::uint64_t clamp_cycles = 0;          // cycles at a travel clamp (follower or limiter)
  double time_at_clamp_s = 0.0;            // clamp_cycles × the servo period
  std::uint64_t sensor_faults = 0;         // cycles with a non-finite base, tip or force reading
  std::uint64_t image_not_responding = 0;  // response-check faults (follower)
};

struct ServoCycle {
  control::CycleRecord record;
  std::optional<std::uint64_t> applied_sequence;  // the estimate taken in this cycle
  link::ServoMode mode = link::ServoMode::kIdle;
  std::uint32_t faults = 0;
  bool clamped = false;  // a travel clamp intervened in this cycle
};

link::ServoMode ToLinkMode(control::FollowerMode mode);
std::uint32_t ToLinkFaults(std::uint32_t follower_faults);

class ServoNode {
 public:
  // `hardware` must be active and outlive the node; `participant` may be null (no link:
  // feed HandleTarget/HandleCommand directly). Throws std::invalid_argument for bad options.
  ServoNode(hw::HardwareInterface& hardware, control::ServoConfig servo,
            std::unique_ptr<control::BacklashCompensator> compensator, ServoNodeOptions options,
            link::Participant* participant);
  ~ServoNode();

  void Start(double t_s);
  ServoCycle Cycle(double t_s, std::uint64_t k);

  // Direct inputs (link samples, link clock); both validate like the subscribers do.
  bool HandleTarget(const link::TargetEstimateSample& s, double t_s);
  bool HandleCommand(const link::ServoCommandSample& s, double t_s);

  link::CatheterStateSample State(double t_s) const;
  const ServoNodeStats& stats() const { return stats_; }
  const control::TargetFollower& follower() const { return follower_; }
  const control::ServoLoop& loop() const { return loop_; }
  link::SubscriberStats target_link_stats() const;
  bool tracker_gone() const { return tracker_gone_; }

 private:
  bool ApplyCommand(const link::ServoCommandSample& c, double t_s);
  bool ApplyTarget(const link::TargetEstimateSample& s, double t_s);
  void CheckLimits(const control::CycleRecord& r);
  std::uint32_t ActiveFaults();

  hw::HardwareInterface& hw_;
  control::ServoLoop loop_;
  std::unique_ptr<control::BacklashCompensator> compensator_;
  ServoNodeOptions o_;
  control::TargetFollower follower_;
  std::size_t tip_index_, base_velocity_index_, fault_count_index_;
  std::unique_ptr<link::TargetSubscriber> target_sub_;
  std::unique_ptr<link::CommandSubscriber> command_sub_;
  std::unique_ptr<link::StatePublisher> state_pub_;
  std::mutex commands_m_;
  std::deque<link::ServoCommandSample> commands_;  // from the DDS thread, ≤ 64
  link::TargetEstimateSample sample_;              // reused storage
  link::SampleValidator direct_validator_;
  bool enabled_once_ = false;
  bool tracker_gone_ = false;
  double next_state_s_ = 0.0;
  std::uint64_t state_sequence_ = 0;
  std::uint32_t last_faults_ = 0;
  std::uint64_t last_travel_ = 0, last_non_finite_ = 0, last_force_ = 0;
  std::uint64_t reference_clamps_ = 0;  // cycles the follower's reference was clamped
  double last_hw_faults_ = 0.0;
  std::uint32_t pending_faults_ = 0;  // limiter/hardware events since the last state
  control::CycleRecord last_;
  double last_finite_tip_mm_ = 0.0;
  ServoNodeStats stats_;
};

}  // namespace echoservo::live
