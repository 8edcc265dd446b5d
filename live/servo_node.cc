#include "live/servo_node.h"

#include <bit>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "hw/hardware_interface.h"

namespace echoservo::live {
namespace {

// The measured base may pass the limiter's travel window by at most the margin it keeps
// inside the slide's end stops (control/command_limiter.h: 1 mm).
constexpr double kEndStopMarginMm = 1.0;

}  // namespace

void ServoNodeOptions::Validate() const {
  follower.Validate();
  limits.Validate();
  if (!(state_rate_hz > 0 && state_rate_hz <= 1000))
    throw std::invalid_argument("ServoNodeOptions: state_rate_hz must be in (0, 1000] Hz");
  if (!std::isfinite(link_offset_s))
    throw std::invalid_argument("ServoNodeOptions: link_offset_s must be finite");
}

link::ServoMode ToLinkMode(control::FollowerMode mode) {
  switch (mode) {
    case control::FollowerMode::kDisabled:
      return link::ServoMode::kIdle;
    case control::FollowerMode::kFollowing:
      return link::ServoMode::kTracking;
    case control::FollowerMode::kHolding:
      return link::ServoMode::kHolding;
    case control::FollowerMode::kRetracting:
      return link::ServoMode::kRetracting;
    case control::FollowerMode::kStopped:
      return link::ServoMode::kStopped;
  }
  return link::ServoMode::kFault;
}

std::uint32_t ToLinkFaults(std::uint32_t f) {
  return f & control::fault::kAll;  // kStopRequested and kRetracted are modes, not faults
}

ServoNode::ServoNode(hw::HardwareInterface& hardware, control::ServoConfig servo,
                     std::unique_ptr<control::BacklashCompensator> compensator,
                     ServoNodeOptions options, link::Participant* participant)
    : hw_(hardware),
      loop_(hardware, servo),
      compensator_(std::move(compensator)),
      o_((options.Validate(), options)),
      follower_(o_.follower),
      tip_index_(hardware.StateIndex(hw::iface::kTipPosition)),
      base_velocity_index_(hardware.StateIndex(hw::iface::kBaseVelocity)),
      fault_count_index_(hardware.StateIndex(hw::iface::kFaultCount)),
      watchdog_((o_.watchdog.Validate(loop_.config().period_s), o_.watchdog),
                loop_.config().period_s),
      direct_validator_(o_.limits) {
  if (!compensator_) throw std::invalid_argument("ServoNode: a backlash compensator is required");
  if (participant) {
    target_sub_ = std::make_unique<link::TargetSubscriber>(*participant, o_.limits);
    command_sub_ = std::make_unique<link::CommandSubscriber>(
        *participant, o_.limits,
        [this](const link::ServoCommandSample& s, double) { EnqueueCommand(s); });
    state_pub_ = std::make_unique<link::StatePublisher>(*participant);
    // Created here, before the caller raises its thread to SCHED_FIFO: this one stays at
    // normal priority (a DDS write may block and allocate).
    publisher_ = std::thread([this] { PublishStates(); });
  }
}

ServoNode::~ServoNode() {
  command_sub_.reset();  // no receive thread enqueues any more
  target_sub_.reset();
  if (publisher_.joinable()) {
    stop_publisher_.store(true, std::memory_order_release);
    state_signal_.fetch_add(1, std::memory_order_release);
    state_signal_.notify_one();
    publisher_.join();
  }
}

void ServoNode::EnqueueCommand(const link::ServoCommandSample& s) {
  std::lock_guard lock(commands_producer_m_);  // producers only: the cycle never takes it
  const bool stop = s.action == link::ServoAction::kStop;
  if (stop) commands_.Clear();  // nothing may delay a stop
  commands_.Push(s);
  if (stop) stop_requests_.fetch_add(1, std::memory_order_release);
}

void ServoNode::TakeCommands(double t_s) {
  // Before the ring: every STOP counted here is in the ring or was overwritten in it.
  const std::uint64_t stops = stop_requests_.load(std::memory_order_acquire);
  bool stopped = false;
  // Validated at reception: applied in the order they came.
  commands_.Drain([&](const link::ServoCommandSample& c) {
    stopped |= c.action == link::ServoAction::kStop;
    ApplyCommand(c, t_s);
  });
  if (stops != stops_handled_ && !stopped) {
    // A STOP followed by more than kMaxQueuedCommands commands within one cycle was
    // overwritten in the ring: it still stops.
    follower_.Stop(t_s);
    ++stats_.commands_applied;
  }
  stops_handled_ = stops;
  stats_.commands_dropped = commands_.lost();
}

void ServoNode::PublishStates() {
  std::uint32_t seen = 0;
  std::uint64_t published_version = 0;
  link::CatheterStateSample s;
  while (true) {
    const std::uint32_t signal = state_signal_.load(std::memory_order_acquire);
    if (signal == seen) {
      if (stop_publisher_.load(std::memory_order_acquire)) return;
      state_signal_.wait(seen, std::memory_order_acquire);
      continue;
    }
    seen = signal;
    const std::uint64_t version = state_slot_.Read(s);
    if (version != 0 && version != published_version) {
      published_version = version;
      bool ok = false;
      try {
        ok = state_pub_->Publish(s);
      } catch (const std::exception&) {  // state samples always fit the IDL: not expected
        ok = false;
      }
      if (ok) states_published_.fetch_add(1, std::memory_order_relaxed);
    }
    states_handled_.store(version, std::memory_order_release);
  }
}

bool ServoNode::WaitStatesPublished(double timeout_s) const {
  if (!publisher_.joinable()) return true;
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (states_handled_.load(std::memory_order_acquire) < state_slot_.version()) {
    if (std::chrono::steady_clock::now() >= until) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  return true;
}

ServoNodeStats ServoNode::stats() const {
  ServoNodeStats s = stats_;
  s.states_published = states_published_.load(std::memory_order_relaxed);
  return s;
}

void ServoNode::NoteWake(double t_s, double lateness_s) {
  ApplyDeadlineAction(watchdog_.Woke(t_s, lateness_s), t_s);
}

void ServoNode::NoteCycleEnd(double t_s, bool overran) {
  ApplyDeadlineAction(watchdog_.CycleEnded(t_s, overran), t_s);
}

void ServoNode::ApplyDeadlineAction(control::DeadlineAction action, double t_s) {
  using control::DeadlineAction;
  if (action != deadline_action_) {
    switch (action) {
      case DeadlineAction::kHold:
        follower_.DeadlineHold(t_s);
        break;
      case DeadlineAction::kRetract:
        follower_.DeadlineRetract(t_s);
        break;
      case DeadlineAction::kNone:  // a hold ended (a retraction ends only by Reset)
        follower_.DeadlineCleared(t_s);
        break;
    }
    deadline_action_ = action;
  }
  stats_.deadline_holds = watchdog_.holds();
  stats_.deadline_retracts = watchdog_.retracts();
}

void ServoNode::ResetWatchdog(double t_s) {
  watchdog_.Reset(t_s);
  deadline_action_ = control::DeadlineAction::kNone;
}

void ServoNode::Start(double t_s) {
  loop_.Start(t_s);
  compensator_->Reset();
  next_state_s_ = t_s;
  last_hw_faults_ = hw_.state(fault_count_index_);
}

link::SubscriberStats ServoNode::target_link_stats() const {
  return target_sub_ ? target_sub_->stats() : link::SubscriberStats{};
}

bool ServoNode::HandleCommand(const link::ServoCommandSample& s, double t_s) {
  if (!direct_validator_.Accept(s, t_s + o_.link_offset_s)) {
    ++stats_.commands_rejected;
    return false;
  }
  return ApplyCommand(s, t_s);
}

bool ServoNode::HandleTarget(const link::TargetEstimateSample& s, double t_s) {
  if (!direct_validator_.Accept(s, t_s + o_.link_offset_s)) {
    ++stats_.estimates_rejected;
    return false;
  }
  return ApplyTarget(s, t_s);
}

bool ServoNode::ApplyCommand(const link::ServoCommandSample& c, double t_s) {
  try {
    switch (c.action) {
      case link::ServoAction::kEnable:
        follower_.SetStandoff(c.standoff_mm);
        follower_.Enable(t_s);
        ResetWatchdog(t_s);
        enabled_once_ = true;
        break;
      case link::ServoAction::kDisable:
      case link::ServoAction::kStop:
        follower_.Stop(t_s);
        break;
      case link::ServoAction::kSetStandoff:
        follower_.SetStandoff(c.standoff_mm);
        break;
    }
  } catch (const std::invalid_argument&) {  // a standoff the follower refuses
    ++stats_.commands_rejected;
    return false;
  }
  ++stats_.commands_applied;
  return true;
}

bool ServoNode::ApplyTarget(const link::TargetEstimateSample& s, double t_s) {
  const double off = o_.link_offset_s;
  control::TargetEstimateInput& in = target_input_;  // copy-assignments reuse its storage
  in.acquired_s = s.acquisition_time_s - off;
  in.published_s = s.publication_time_s - off;
  in.target_motion = s.motion;
  in.target_motion.t0_s -= off;
  in.target_motion.valid_until_s -= off;
  in.tip_axis_mm = s.tip_mm.dot(s.axis);
  in.confidence = s.confidence;
  if (!follower_.Accept(in, t_s)) {
    ++stats_.estimates_rejected;
    return false;
  }
  ++stats_.estimates_accepted;
  // Auto-enable resumes after a lost tracker, never after the image stopped answering or
  // the loop missed its deadlines for too long (those latch until an operator's ENABLE).
  if (o_.auto_enable &&
      (!enabled_once_ || (follower_.mode() == control::FollowerMode::kRetracting &&
                          !(follower_.faults() & control::fault::kImageNotResponding) &&
                          deadline_action_ != control::DeadlineAction::kRetract))) {
    if (enabled_once_) ++stats_.resumes;
    follower_.Enable(t_s);
    ResetWatchdog(t_s);
    enabled_once_ = true;
  }
  return true;
}

void ServoNode::CheckLimits(const control::CycleRecord& r) {
  const control::Limits& l = loop_.limiter().limits();
  const double sp = loop_.limiter().setpoint_mm();
  const double v = loop_.limiter().setpoint_velocity_mm_s();
  const double eps = 1e-9;
  const bool bad = !(sp >= l.travel_min_mm - eps && sp <= l.travel_max_mm + eps) ||
                   !(std::abs(v) <= l.max_velocity_mm_s * (1 + eps)) ||
                   !(std::abs(r.actuator_force_n) <= l.max_force_n * (1 + eps)) ||
                   (std::isfinite(r.base_mm) &&  // a NaN reading is a sensor fault, not a command
                    !(r.base_mm >= l.travel_min_mm - kEndStopMarginMm &&
                      r.base_mm <= l.travel_max_mm + kEndStopMarginMm));
  if (bad) ++stats_.limit_violations;
}

std::uint32_t ServoNode::ActiveFaults() {
  std::uint32_t f = ToLinkFaults(follower_.faults()) | pending_faults_;
  if (tracker_gone_) f |= link::fault::kTrackerLost;
  return f;
}

ServoCycle ServoNode::Cycle(double t_s, std::uint64_t k) {
  ServoCycle out;
  TakeCommands(t_s);
  if (target_sub_ && target_sub_->TryTakeLatest(sample_) && ApplyTarget(sample_, t_s))
    out.applied_sequence = sample_.sequence_number;
  const double tip_reading = hw_.state(tip_index_);
  if (std::isfinite(tip_reading)) last_finite_tip_mm_ = tip_reading;
  follower_.Update(t_s, last_finite_tip_mm_);
  out.record = loop_.Cycle(t_s, static_cast<std::size_t>(k), follower_, *compensator_);
  last_ = out.record;
  ++stats_.cycles;
  CheckLimits(out.record);
  // A sensor that reads NaN/inf (base, tip, force): the safe state is a stop — hold where
  // the tip was, until the operator enables again.
  if (out.record.sensor_fault || !std::isfinite(out.record.force_n)) {
    ++stats_.sensor_faults;
    pending_faults_ |= link::fault::kNonFinite | link::fault::kHardware;
    if (follower_.mode() != control::FollowerMode::kStopped) follower_.Stop(t_s);
  }

  // Limiter and hardware events since the last state.
  const control::CommandLimiter& lim = loop_.limiter();
  using control::LimitEvent;
  const bool limiter_clamped = lim.count(LimitEvent::kTravel) != last_travel_;
  if (limiter_clamped) pending_faults_ |= link::fault::kTravelLimit;
  // The follower's own clamp (its travel window lies inside the limiter's) is an
  // intervention too: counted per cycle, like the limiter's.
  const bool reference_clamped = follower_.reference_clamped();
  if (reference_clamped) ++reference_clamps_;
  out.clamped = reference_clamped || limiter_clamped;
  if (out.clamped) {
    ++stats_.clamp_cycles;
    stats_.time_at_clamp_s += loop_.config().period_s;
  }
  if (lim.count(LimitEvent::kNonFinite) != last_non_finite_)
    pending_faults_ |= link::fault::kNonFinite;
  if (lim.count(LimitEvent::kForce) != last_force_) pending_faults_ |= link::fault::kForceLimit;
  last_travel_ = lim.count(LimitEvent::kTravel);
  last_non_finite_ = lim.count(LimitEvent::kNonFinite);
  last_force_ = lim.count(LimitEvent::kForce);
  stats_.limit_interventions = lim.faults() + reference_clamps_;
  stats_.image_not_responding = follower_.counters().image_not_responding_events;
  const double hw_faults = hw_.state(fault_count_index_);
  if (hw_faults != last_hw_faults_) pending_faults_ |= link::fault::kHardware;
  last_hw_faults_ = hw_faults;

  if (t_s >= next_state_s_) {
    next_state_s_ = t_s + 1.0 / o_.state_rate_hz;
    if (target_sub_) tracker_gone_ = target_sub_->publisher_gone_now();
    if (publisher_.joinable()) {  // the publisher thread writes it to DDS
      state_slot_.Write(State(t_s));
      state_signal_.fetch_add(1, std::memory_order_release);
      state_signal_.notify_one();  // a futex wake when it waits; nothing when it does not
    }
    ++state_sequence_;
    pending_faults_ = 0;
  }
  const std::uint32_t faults = ActiveFaults();
  stats_.fault_events += static_cast<std::uint64_t>(std::popcount(faults & ~last_faults_));
  last_faults_ = faults;
  out.mode = ToLinkMode(follower_.mode());
  out.faults = faults;
  return out;
}

link::CatheterStateSample ServoNode::State(double t_s) const {
  link::CatheterStateSample s;
  s.sequence_number = state_sequence_ + 1;
  s.stamp_s = t_s + o_.link_offset_s;
  s.mode = ToLinkMode(follower_.mode());
  s.faults = ToLinkFaults(follower_.faults()) | pending_faults_ |
             (tracker_gone_ ? link::fault::kTrackerLost : 0u);
  s.fault_count = stats_.fault_events;
  // The state topic carries numbers only (a NaN would be rejected by every reader): a
  // sensor that reads NaN is reported through the fault bits, its value as 0.
  auto finite = [](double v) { return std::isfinite(v) ? v : 0.0; };
  s.base_mm = finite(last_.base_mm);
  s.base_velocity_mm_s = finite(hw_.state(base_velocity_index_));
  s.tip_estimate_mm = finite(last_.tip_mm);
  s.setpoint_mm = finite(last_.reference_mm);
  s.force_n = finite(last_.force_n);
  s.standoff_mm = follower_.config().standoff_mm;
  s.estimate_age_s =
      follower_.has_estimate() ? std::max(0.0, t_s - follower_.newest_acquired_s()) : 0.0;
  return s;
}

}  // namespace echoservo::live
