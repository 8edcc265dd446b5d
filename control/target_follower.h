// The live servo's reference: keep the catheter tip a chosen standoff short of the moving
// target, along the catheter axis, from the tracker's predicted motion model.
//
// In: target estimates (a FourierMotion of the target's axis coordinate s in image mm, on the
// pipeline clock in s) and the servo's tip x (catheter mm) every cycle. Out: the reference
// x_ref(t) = (s_target(t) − standoff − c)/k with its velocity and acceleration, c the
// image↔catheter offset and k their scale (estimate_scale; else k = 1), both fitted online.
// Supervisor (Update, every cycle): disabled until Enable; Stop holds at once; a stale
// estimate holds, then retracts; travel clamp; rejected estimates are counted and ignored.
// Response check (check_response): over a sliding window of volumes, the slope of the imaged
// tip s on the servo's tip x at acquisition; with enough excitation and a slope below
// response_min_gain the image is not answering the catheter: fault kImageNotResponding
// (latched until Enable), hold, then retract; c and k are frozen while it is active and c
// never moves more than max_offset_change_mm from its first measurement.
// Missed deadlines (control/deadline_watchdog.h): DeadlineHold holds the tip (fault
// kDeadlineHold) until DeadlineCleared, DeadlineRetract starts the retract motion at once (fault
// kDeadlineRetract, until Enable). Update and Evaluate never allocate: the tip history is a
// ring of history_capacity samples allocated by the constructor; Accept allocates only when
// the response window holds more volumes than ever before.
// Errors: std::invalid_argument for a bad config or a standoff outside [0, 30] mm.
// Details: docs/control.md#following-the-target-controltarget_followerh
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "control/fault_bits.h"
#include "control/trajectory.h"
#include "estimation/fourier_motion.h"
#include "formats/parameter_spec.h"

namespace echoservo::control {

// One tracker output, as the servo receives it.
struct TargetEstimateInput {
  double acquired_s = 0.0;                  // the volume's acquisition time (pipeline clock)
  double published_s = 0.0;                 // when the tracker published it
  estimation::FourierMotion target_motion;  // target's axis coordinate s(t), mm
  double tip_axis_mm = 0.0;                 // the tracked tip's axis coordinate at acquisition
  double confidence = 0.0;                  // detector confidence, [0, 1]
};

// The follower's tunable parameters (formats/parameter_spec.h): declared once, read by the
// defaults below, by Validate and by the pipeline's registry (live/pipeline_parameters.h,
// stage "follower"; the live pipeline's own standoff and scale fit: live::PipelineSettings).
namespace params {
inline constexpr formats::ParameterSpec kStandoffMm{
    "follower.standoff_mm",
    "mm",
    formats::ParameterKind::kReal,
    0,
    30,
    3.0,
    "the tip is held this far short of the target along the axis (0: contact)"};
inline constexpr formats::ParameterSpec kStaleAfterS{
    "follower.stale_after_s",
    "s",
    formats::ParameterKind::kReal,
    0.02,
    5,
    0.25,
    "no fresh estimate for this long: hold (then retract); >= one volume interval at 60 vol/s"};
inline constexpr formats::ParameterSpec kOffsetGain{
    "follower.offset_gain",
    "1",
    formats::ParameterKind::kReal,
    1e-3,
    1,
    0.2,
    "low-pass gain per volume of the image-to-catheter offset (1: the newest volume's alone)"};
inline constexpr formats::ParameterSpec kEstimateScale{
    "follower.estimate_scale",
    "1",
    formats::ParameterKind::kBool,
    0,
    1,
    0,
    "1: fit the image/catheter scale online (a sound speed other than the scanner's makes "
    "image mm differ from catheter mm); 0: scale 1"};
inline constexpr formats::ParameterSpec kMinConfidence{
    "follower.min_confidence",
    "1",
    formats::ParameterKind::kReal,
    0,
    1,
    0.5,
    "the servo ignores estimates below this confidence (counted)"};
}  // namespace params

struct FollowerConfig {
  double standoff_mm =
      params::kStandoffMm.default_value;  // tip held this far short of the target, [0, 30]
  double stale_after_s =
      params::kStaleAfterS.default_value;  // no fresh estimate for this long: hold
  double retract_after_s = 0.5;            // holding this long: retract
  double retract_mm = 5.0;                 // retraction distance
  double retract_speed_mm_s = 20.0;
  double travel_min_mm = -15.0;  // reference clamp (catheter coordinates)
  double travel_max_mm = 15.0;
  double offset_gain =
      params::kOffsetGain.default_value;  // low-pass gain of the image↔catheter offset per volume
  bool estimate_scale = params::kEstimateScale.default_value !=
                        0.0;     // fit the image/catheter scale k (see above); false: k = 1
  double scale_gain = 0.01;      // the scale fit's weight of each new volume, (0, 1]
  double scale_prior_sd = 0.05;  // prior k = 1 ± this, (0, 1]
  double tip_noise_mm = 0.2;     // the detected tip's noise σ (weighs the prior), (0, 10]
  double min_confidence =
      params::kMinConfidence.default_value;  // estimates below are ignored (counted)
  double max_future_s = 0.05;  // acquisition/publication this far ahead of now: rejected
  // The image↔catheter offset stays within ± this of its first measurement, (0, 100] mm.
  double max_offset_change_mm = 5.0;
  // Response check (docs/control.md#the-image-response-check).
  bool check_response = true;
  double response_window_s = 2.0;           // volumes acquired this long before the newest, (0, 10]
  double response_delay_s = 0.0;            // image behind its acquisition stamp, [0, 0.5] s
  double response_min_excitation_mm = 0.3;  // SD of the tip over the window to judge, (0, 10]
  double response_max_gain_se = 0.1;  // judge once tip_noise_mm/√Σ(x−x̄)² ≤ this, (0, 1]
  std::size_t response_min_volumes = 8;  // volumes in the window to judge, [3, 10000]
  double response_min_gain = 0.3;        // image mm per catheter mm below this: fault, [0, 1)
  // Servo tip samples kept for the tip at acquisition (the last 1 s at most): at least 1 s of
  // servo cycles; 2048 covers 1 kHz with margin. [16, 1000000]; allocated once, at construction.
  std::size_t history_capacity = 2048;
  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

enum class FollowerMode : std::uint8_t { kDisabled, kFollowing, kHolding, kRetracting, kStopped };
std::string ToString(FollowerMode mode);

// Fault bits: control/fault_bits.h (one set with the link's).

struct FollowerCounters {
  std::uint64_t accepted = 0;
  std::uint64_t rejected_non_finite = 0;
  std::uint64_t rejected_range = 0;
  std::uint64_t rejected_time = 0;
  std::uint64_t rejected_confidence = 0;
  std::uint64_t stale_events = 0;
  std::uint64_t image_not_responding_events = 0;  // response-check faults raised
  std::uint64_t offset_bounded = 0;               // estimates whose offset hit its bound
};

// The response check's window, as of the newest accepted estimate.
struct ResponseCheck {
  std::size_t volumes = 0;
  double excitation_mm = 0.0;  // SD of the servo's tip x over the window
  double gain = 0.0;           // slope of the imaged tip s on x (image mm per catheter mm)
  double gain_se = 0.0;        // its standard error from tip_noise_mm; inf without excitation
  double correlation = 0.0;    // of s and x
  bool judged = false;         // enough excitation and volumes for a verdict
};

class TargetFollower final : public Trajectory {
 public:
  // Throws std::invalid_argument for a bad config.
  explicit TargetFollower(FollowerConfig config);

  // Commands. Enable resumes following (from stop, hold or retraction) at the next
  // estimate; Stop holds the current tip at once.
  void Enable(double now_s);
  void Stop(double now_s);
  // Throws std::invalid_argument outside [0, 30] mm or non-finite.
  void SetStandoff(double standoff_mm);

  // A tracker estimate; false (and counted) when rejected. Uses the servo's tip history.
  bool Accept(const TargetEstimateInput& estimate, double now_s);
  // Every servo cycle, before Evaluate: records the tip and runs the supervisor.
  void Update(double now_s, double tip_mm);

  // The deadline watchdog's actions (control/deadline_watchdog.h); each may be called once
  // at the transition or every cycle while the action is in force. DeadlineHold holds the
  // tip where it is (as a stale estimate does, so a hold that lasts retract_after_s retracts);
  // fresh estimates do not end it. DeadlineCleared ends it: back to following when no other
  // hold reason is active and the estimate is fresh (else the hold goes on, as stale if the
  // estimate is). DeadlineRetract starts the follower's retract motion at once, from the held
  // tip (or the tip now), latched until Enable. A disabled or stopped follower only gets the
  // fault bit: it moves on the operator's command only.
  void DeadlineHold(double now_s);
  void DeadlineCleared(double now_s);
  void DeadlineRetract(double now_s);

  MotionSample Evaluate(double t_s) const override;
  std::string name() const override { return "target_follower"; }

  FollowerMode mode() const { return mode_; }
  std::uint32_t faults() const { return faults_; }
  const FollowerCounters& counters() const { return counters_; }
  double offset_mm() const { return offset_mm_; }
  double scale() const { return scale_; }  // image mm per catheter mm (1 without estimate_scale)
  const ResponseCheck& response() const { return response_; }
  // The reference at the last Update's time lay outside the travel clamp.
  bool reference_clamped() const { return reference_clamped_; }
  bool has_estimate() const { return has_estimate_; }
  double newest_acquired_s() const { return estimate_.acquired_s; }
  const FollowerConfig& config() const { return config_; }

 private:
  double TipAt(double t_s) const;  // the servo's tip history, interpolated
  // The i-th oldest sample of the tip history (i < tip_count_).
  const std::pair<double, double>& TipSample(std::size_t i) const {
    return tip_ring_[(tip_head_ + i) % tip_ring_.size()];
  }
  MotionSample Raw(double t_s) const;  // the reference before the travel clamp
  void CheckResponse(double acquired_s, double tip_axis_mm, double now_s);
  void Hold(double now_s, std::uint32_t fault);
  MotionSample Clamp(MotionSample m) const;  // sets kTravelLimit when it clamps

  FollowerConfig config_;
  FollowerMode mode_ = FollowerMode::kDisabled;
  mutable std::uint32_t faults_ = 0;  // Evaluate (const, per cycle) flags the travel limit
  FollowerCounters counters_;
  TargetEstimateInput estimate_;
  bool has_estimate_ = false;
  bool offset_known_ = false;
  double offset_mm_ = 0.0;
  double offset_anchor_mm_ = 0.0;  // the first measured offset
  bool reference_clamped_ = false;
  ResponseCheck response_;
  struct ResponsePoint {
    double acquired_s, tip_x_mm, tip_s_mm;  // the servo's tip x and the imaged tip s
  };
  // The response check's window, oldest first: a ring that starts with room for 256 volumes
  // (10 s at 25 vol/s) and doubles only when a window holds more than ever before.
  std::vector<ResponsePoint> response_ring_;
  std::size_t response_head_ = 0, response_count_ = 0;
  const ResponsePoint& ResponseAt(std::size_t i) const {
    return response_ring_[(response_head_ + i) % response_ring_.size()];
  }
  void PushResponse(const ResponsePoint& p);
  // The scale fit: weighted means of x_tip and s_tip, their (co)variance, and the slope.
  double scale_ = 1.0;
  double mean_x_ = 0.0, mean_s_ = 0.0, var_x_ = 0.0, cov_xs_ = 0.0;
  double last_estimate_s_ = -1e300;  // receipt time of the newest accepted estimate
  double hold_mm_ = 0.0;
  double hold_since_s_ = 0.0;
  double tip_mm_ = 0.0;
  // (t, tip) of the last 1 s of cycles, at most history_capacity: a ring, oldest at tip_head_.
  std::vector<std::pair<double, double>> tip_ring_;
  std::size_t tip_head_ = 0, tip_count_ = 0;
};

}  // namespace echoservo::control
