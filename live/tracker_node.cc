#include "live/tracker_node.h"

#include <stdexcept>
#include <string>

#include "formats/run_record.h"

namespace echoservo::live {

estimation::HeartbeatEkfOptions TrackerNodeOptions::DefaultEkfOptions() {
  estimation::HeartbeatEkfOptions o;
  o.init_window_s = 2.0;
  o.max_harmonics = 8;
  // A fixed count: the automatic choice validates on what a 2 s window leaves past
  // 1/min_rate (0.33 s, ~8 volumes) and picked 2 harmonics on demo seed 3 (1.16 mm); the
  // mitral shape needs 7–8 (docs/predictor.md: fixed 7–8 within 0.025 mm of the best).
  o.harmonics = 8;
  return o;
}

estimation::PredictorCompetitionOptions TrackerNodeOptions::CompetitionOptions() const {
  estimation::PredictorCompetitionOptions c;
  c.ekf = ekf;
  c.latency_s = prediction_latency_s;
  return c;
}

void TrackerNodeOptions::Validate() const {
  params::kPredictionLatencyS.Check(prediction_latency_s, "TrackerNodeOptions");
  params::kStampDelayS.Check(stamp_delay_s, "TrackerNodeOptions");
  detector.Validate();
  estimation::HeartbeatEkf check(ekf);  // the EKF's own validation
}

TrackerNode::TrackerNode(TrackerNodeOptions options, link::TargetPublisher* publisher,
                         formats::RunWriter* writer)
    : o_(std::move(options)),
      publisher_(publisher),
      writer_(writer),
      detector_(o_.detector),
      competition_(o_.CompetitionOptions()),
      significance_(o_.significance) {
  o_.Validate();
}

TrackedVolume TrackerNode::Process(const imaging::Volume& volume, double stamp_s, double arrived_s,
                                   const std::function<double()>& now_s) {
  const double acquired_s = stamp_s - o_.stamp_delay_s;
  TrackedVolume out;
  ++stats_.volumes;
  auto fail = [&](const std::exception& e) {
    ++stats_.errors;
    out.error = e.what();
    return out;
  };
  try {
    out.detection = detector_.Track(volume);
  } catch (const std::exception& e) {  // a volume the detector cannot judge
    return fail(e);
  }
  const tracking::CatheterDetection& det = out.detection;
  if (!(det.found && det.target_found)) {
    ++stats_.not_found;
    if (writer_)
      writer_->AddTarget(
          {acquired_s, arrived_s, std::max(arrived_s, now_s()), false, {}, {}, {}, det.confidence});
    return out;
  }
  if (!reference_axis_) reference_axis_ = det.axis.direction;
  const double s_target = det.target_mm.dot(*reference_axis_);
  const bool hold = o_.predictor == TargetPredictor::kZeroOrderHold;
  try {
    if (!hold) {
      competition_.Update(acquired_s, s_target);
      significance_.Add(acquired_s, s_target);
      significance_.Evaluate();
    }
  } catch (const std::exception& e) {  // a measurement out of order or non-finite
    return fail(e);
  }
  // The competition's motion only when the trace shows a heartbeat; else hold the newest
  // measurement.
  const bool heartbeat = !hold && significance_.evidence().significant;
  out.measured = true;
  ++stats_.measured;
  out.published_s = std::max(arrived_s, now_s());
  if (hold || competition_.ekf().initialised()) {
    link::TargetEstimateSample s;
    s.sequence_number = ++sequence_;
    s.acquisition_time_s = acquired_s + o_.link_offset_s;
    s.publication_time_s = out.published_s + o_.link_offset_s;
    s.target_mm = det.target_mm;
    s.axis = *reference_axis_;
    s.tip_mm = det.tip_mm;
    if (!heartbeat) {  // s(t) = the newest measurement, valid as long as the EKF's model would be
      s.motion = estimation::FourierMotion{};
      s.motion.t0_s = acquired_s;
      s.motion.offset_mm = s_target;
      s.motion.valid_until_s = acquired_s + o_.ekf.horizon_s;
    } else {
      s.motion = competition_.Motion();
    }
    s.motion.t0_s += o_.link_offset_s;
    s.motion.valid_until_s += o_.link_offset_s;
    // The zero-order-hold baseline keeps the detector's confidence; the EKF's output is as
    // credible as the heartbeat in the trace (0 when there is none: no invented heartbeat).
    s.confidence = hold || (!heartbeat && o_.follow_static_target)
                       ? det.confidence
                       : det.confidence * significance_.evidence().confidence();
    out.sequence = s.sequence_number;
    out.heartbeat = heartbeat;
    out.confidence = s.confidence;
    if (publisher_) {
      out.published = publisher_->Publish(s);
      if (out.published) {
        ++stats_.published;
        if (!hold) ++(heartbeat ? stats_.published_heartbeat : stats_.published_hold);
      } else {
        ++stats_.publish_failures;
      }
    }
    out.estimate = std::move(s);
  }
  if (writer_)
    writer_->AddTarget({acquired_s, arrived_s, out.published_s, true, det.target_mm, det.tip_mm,
                        det.axis.direction, det.confidence});
  return out;
}

}  // namespace echoservo::live
