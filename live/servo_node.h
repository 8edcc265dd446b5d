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
// Real time: once warm, Cycle neither allocates nor takes a lock that can block. Commands
// reach it from the DDS receive threads through a lock-free ring (live/lock_free.h; a STOP
// drops what was queued before it); states leave through a wait-free slot that a publisher
// thread of normal priority, created by the constructor, writes to DDS. The loop driver
// reports each wake-up and cycle end (NoteWake, NoteCycleEnd) to the deadline watchdog
// (control/deadline_watchdog.h), whose hold and retraction go to the follower.
// Errors: the constructor throws std::invalid_argument for bad options.
// Details: docs/live.md#the-servo-node-liveservo_nodeh
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "control/deadline_watchdog.h"
#include "control/servo_loop.h"
#include "control/target_follower.h"
#include "link/dds_link.h"
#include "live/lock_free.h"

namespace echoservo::live {

struct ServoNodeOptions {
  control::FollowerConfig follower;
  double state_rate_hz = 100.0;  // (0, 1000]
  // Enable at the first accepted estimate and again after a retraction (the demo and
  // tests); otherwise the servo waits for an ENABLE command.
  bool auto_enable = false;
  double link_offset_s = 0.0;  // link time − node time
  link::ValidationLimits limits;
  // Missed deadlines: hold after K consecutive overruns, retract after an outage. Checked
  // against the servo's period by the node's constructor (throws naming the option).
  control::DeadlineWatchdogConfig watchdog;
  void Validate() const;  // throws std::invalid_argument naming the field
};

struct ServoNodeStats {
  std::uint64_t cycles = 0;
  std::uint64_t estimates_accepted = 0, estimates_rejected = 0;  // by the follower
  std::uint64_t commands_applied = 0, commands_rejected = 0;     // rejected: bad standoff
  std::uint64_t commands_dropped = 0;  // oldest queued commands overwritten (ring full)
  std::uint64_t states_published = 0;  // by the publisher thread (stats() reads it fresh)
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
  std::uint64_t deadline_holds = 0;        // the deadline watchdog's holds
  std::uint64_t deadline_retracts = 0;     // and retractions
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
  static constexpr std::size_t kMaxQueuedCommands = 64;

  // `hardware` must be active and outlive the node; `participant` may be null (no link:
  // feed HandleTarget/HandleCommand directly). With a participant, the state publisher
  // thread starts here: construct the node before raising the servo thread to SCHED_FIFO.
  // Throws std::invalid_argument for bad options.
  ServoNode(hw::HardwareInterface& hardware, control::ServoConfig servo,
            std::unique_ptr<control::BacklashCompensator> compensator, ServoNodeOptions options,
            link::Participant* participant);
  ~ServoNode();  // stops the publisher thread (after it published the newest state)
  ServoNode(const ServoNode&) = delete;
  ServoNode& operator=(const ServoNode&) = delete;

  void Start(double t_s);
  ServoCycle Cycle(double t_s, std::uint64_t k);

  // The loop driver, around each Cycle: the cycle due at its deadline woke `lateness_s`
  // late (at t_s), and its work ended at t_s, past the next deadline when `overran`
  // (control/cycle_timing.h). The watchdog's hold, its end and its retraction go to the
  // follower at once; the fault bits show from the next Cycle on.
  void NoteWake(double t_s, double lateness_s);
  void NoteCycleEnd(double t_s, bool overran);

  // Direct inputs (link samples, link clock); both validate like the subscribers do.
  bool HandleTarget(const link::TargetEstimateSample& s, double t_s);
  bool HandleCommand(const link::ServoCommandSample& s, double t_s);
  // Queues an already validated command for the next Cycle, as the command subscriber's
  // receive thread does (any thread; producers serialize on a mutex the cycle never takes).
  // A STOP drops what was queued before it; a full queue drops its oldest (commands_dropped).
  void EnqueueCommand(const link::ServoCommandSample& s);
  // Commands queued so far (any thread).
  std::uint64_t commands_queued() const { return commands_.pushed(); }

  link::CatheterStateSample State(double t_s) const;
  // The statistics as of the last Cycle; states_published as of now.
  ServoNodeStats stats() const;
  // Waits up to `timeout_s` until the publisher thread has handled the newest state Cycle
  // wrote (tests, and the end of a run); true when it has (or there is no link).
  bool WaitStatesPublished(double timeout_s) const;
  const control::DeadlineWatchdog& watchdog() const { return watchdog_; }
  const control::TargetFollower& follower() const { return follower_; }
  const control::ServoLoop& loop() const { return loop_; }
  link::SubscriberStats target_link_stats() const;
  bool tracker_gone() const { return tracker_gone_; }

 private:
  bool ApplyCommand(const link::ServoCommandSample& c, double t_s);
  bool ApplyTarget(const link::TargetEstimateSample& s, double t_s);
  void CheckLimits(const control::CycleRecord& r);
  std::uint32_t ActiveFaults();
  void TakeCommands(double t_s);
  void ApplyDeadlineAction(control::DeadlineAction action, double t_s);
  void ResetWatchdog(double t_s);
  void PublishStates();  // the publisher thread

  hw::HardwareInterface& hw_;
  control::ServoLoop loop_;
  std::unique_ptr<control::BacklashCompensator> compensator_;
  ServoNodeOptions o_;
  control::TargetFollower follower_;
  std::size_t tip_index_, base_velocity_index_, fault_count_index_;
  control::DeadlineWatchdog watchdog_;
  control::DeadlineAction deadline_action_ = control::DeadlineAction::kNone;
  // Commands from the DDS receive threads (producers, serialized on commands_producer_m_)
  // to the cycle (the consumer, lock-free). stop_requests_ counts STOPs queued, so that a
  // STOP lost to a full ring still stops.
  std::mutex commands_producer_m_;
  LossyRing<link::ServoCommandSample, kMaxQueuedCommands> commands_;
  std::atomic<std::uint64_t> stop_requests_{0};
  std::uint64_t stops_handled_ = 0;  // cycle
  // States from the cycle to the publisher thread: the newest in a seqlock slot, a signal
  // word it waits on (futex), and what it has handled.
  LatestSlot<link::CatheterStateSample> state_slot_;
  std::atomic<std::uint32_t> state_signal_{0};
  std::atomic<bool> stop_publisher_{false};
  std::atomic<std::uint64_t> states_published_{0}, states_handled_{0};
  std::unique_ptr<link::TargetSubscriber> target_sub_;
  std::unique_ptr<link::CommandSubscriber> command_sub_;
  std::unique_ptr<link::StatePublisher> state_pub_;
  std::thread publisher_;
  link::TargetEstimateSample sample_;          // reused storage
  control::TargetEstimateInput target_input_;  // reused storage (its harmonics' vectors)
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
