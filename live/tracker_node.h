// The tracker node of the live pipeline: one volume in → catheter and target detected
// (tracking/radon_detector.h, tracking mode) → the target's axis coordinate into the
// predictor competition (estimation/predictor_competition.h: heartbeat EKF, autoregressive
// predictor, baselines; the best recent one ships) → the predicted motion published as a target
// estimate on the DDS link (link/dds_link.h) → a row in the RUN directory
// (formats/run_record.h). `echoservo track` and `echoservo demo` drive the same node.
//
// Clocks: the caller's times (acquisition, arrival, now) are on one node clock in s; link
// stamps = node time + link_offset_s. Axis coordinates (mm) along the first detection's axis
// from the image origin. Errors in one volume are counted and reported in the result (the
// node goes on); the constructor throws std::invalid_argument for bad options.
// Details: docs/live.md#the-tracker-node-livetracker_nodeh
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "estimation/heartbeat_ekf.h"
#include "estimation/heartbeat_significance.h"
#include "estimation/predictor_competition.h"
#include "formats/parameter_spec.h"
#include "imaging/volume.h"
#include "link/dds_link.h"
#include "tracking/radon_detector.h"

namespace echoservo::formats {
class RunWriter;
}

namespace echoservo::live {

// What the node publishes as the target's motion: the predictor competition's (the heartbeat
// EKF's Fourier model when it is the best recent predictor, else the chosen predictor's
// forward prediction as a line), or the zero-order hold of the newest measurement (the
// baseline: a constant model, no prediction through the delay). With kHeartbeatEkf, the
// prediction goes out only
// while the heartbeat significance test (estimation/heartbeat_significance.h) passes on the
// measured trace; otherwise the zero-order hold goes out with confidence 0 (no heartbeat is
// invented on a static or non-periodic target) and heartbeat().reason says why.
enum class TargetPredictor { kHeartbeatEkf, kZeroOrderHold };

// The tracker node's own tunable parameters (formats/parameter_spec.h): declared once, read by
// the defaults below, by Validate and by the pipeline's registry (live/pipeline_parameters.h).
namespace params {
inline constexpr formats::ParameterSpec kPredictionLatencyS{
    "predictor.latency_s",
    "s",
    formats::ParameterKind::kReal,
    0,
    1,
    0.1,
    "the horizon the predictor competition scores its competitors at: the imaging delay plus "
    "publication"};
inline constexpr formats::ParameterSpec kStampDelayS{
    "scanner.stamp_delay_s",
    "s",
    formats::ParameterKind::kReal,
    0,
    0.5,
    0.0,
    "how late the scanner stamps its volumes after acquiring them (stamped at sending: PLUS's "
    "LocalTimeOffsetSec of a video device); the tracker subtracts it"};
inline constexpr formats::ParameterSpec kZeroOrderHold{
    "predictor.zero_order_hold",
    "1",
    formats::ParameterKind::kBool,
    0,
    1,
    0,
    "1: publish the newest measurement as a constant (the baseline: no prediction through the "
    "delay) instead of the predictor competition's motion"};
}  // namespace params

struct TrackerNodeOptions {
  TargetPredictor predictor = TargetPredictor::kHeartbeatEkf;
  tracking::RadonDetectorOptions detector;
  estimation::HeartbeatEkfOptions ekf = DefaultEkfOptions();
  estimation::HeartbeatSignificanceOptions significance;
  // Without a significant heartbeat, publish the hold at the detector's confidence (a static
  // phantom or bench target the servo should still follow) instead of at confidence 0.
  bool follow_static_target = false;
  double link_offset_s = 0.0;  // link time − node time
  // The horizon the competitors are scored at (s): the imaging delay plus publication.
  double prediction_latency_s = params::kPredictionLatencyS.default_value;
  // The scanner stamps volumes this long after their acquisition (it stamps at sending, not
  // at acquisition: PLUS's LocalTimeOffsetSec of a video device): Process subtracts it from
  // the acquisition time it is given. [0, 0.5] s.
  double stamp_delay_s = params::kStampDelayS.default_value;

  // The live defaults: a 2 s initial window, 8 harmonics.
  static estimation::HeartbeatEkfOptions DefaultEkfOptions();
  // Throws std::invalid_argument naming the parameter (this node's, the detector's, the EKF's).
  void Validate() const;
  // The competition's options from these (EKF options, latency).
  estimation::PredictorCompetitionOptions CompetitionOptions() const;
};

// What the node did with one volume.
struct TrackedVolume {
  tracking::CatheterDetection detection;
  bool measured = false;       // catheter and target found, EKF updated
  bool published = false;      // an estimate went out (EKF initialised, link present)
  bool heartbeat = false;      // the EKF's heartbeat model went out (else a hold, if any)
  double confidence = 0.0;     // the published confidence
  std::uint64_t sequence = 0;  // its sequence number
  double published_s = 0.0;    // node clock
  std::string error;           // non-empty when the volume could not be processed
  // The estimate the node published, or, without a link, would have published (a replay
  // scores it: tune/trial.h); nullopt when none went out (not measured, EKF not initialised).
  std::optional<link::TargetEstimateSample> estimate;
};

struct TrackerStats {
  std::uint64_t volumes = 0, measured = 0, not_found = 0, published = 0, errors = 0,
                publish_failures = 0;
  // Published estimates with the EKF's heartbeat, and held (no significant heartbeat).
  std::uint64_t published_heartbeat = 0, published_hold = 0;
};

class TrackerNode {
 public:
  // `publisher` (may be null: no link) and `writer` (may be null: no RUN directory) must
  // outlive the node. Throws std::invalid_argument for bad options. Volumes are recorded by
  // the caller (imaging::AsyncSequenceWriter, off the estimate's path).
  TrackerNode(TrackerNodeOptions options, link::TargetPublisher* publisher,
              formats::RunWriter* writer);

  // Processes one volume stamped `stamp_s` (acquired stamp_delay_s earlier) that arrived at
  // `arrived_s`; `now_s` gives the node clock (the publication time is taken after detection
  // and EKF).
  TrackedVolume Process(const imaging::Volume& volume, double stamp_s, double arrived_s,
                        const std::function<double()>& now_s);

  const TrackerStats& stats() const { return stats_; }
  const estimation::HeartbeatEkf& ekf() const { return competition_.ekf(); }
  // The competition behind the published motion: chosen predictor, recent errors.
  const estimation::PredictorCompetition& competition() const { return competition_; }
  // The significance test on the newest measurements: whether a heartbeat is published, and
  // why (not).
  const estimation::HeartbeatEvidence& heartbeat() const { return significance_.evidence(); }
  // The axis direction of the link's coordinates (nullopt before the first detection).
  const std::optional<Eigen::Vector3d>& reference_axis() const { return reference_axis_; }

 private:
  TrackerNodeOptions o_;
  link::TargetPublisher* publisher_;
  formats::RunWriter* writer_;
  tracking::RadonDetector detector_;
  estimation::PredictorCompetition competition_;
  estimation::HeartbeatSignificance significance_;
  std::optional<Eigen::Vector3d> reference_axis_;
  std::uint64_t sequence_ = 0;
  TrackerStats stats_;
};

}  // namespace echoservo::live
