#include "apps/live/tracker_node.h"

#include "hw/run_record.h"

namespace echoservo::live {

estimation::HeartbeatEkfOptions TrackerNodeOptions::DefaultEkfOptions() {
  estimation::HeartbeatEkfOptions o;
  o.init_window_s = 2.0;
  o.max_harmonics = 8;
  return o;
}

TrackerNode::TrackerNode(TrackerNodeOptions options, link::TargetPublisher* publisher, hw::RunWriter* writer)
    : o_(std::move(options)), publisher_(publisher), writer_(writer), detector_(o_.detector), ekf_(o_.ekf) {}

TrackedVolume TrackerNode::Process(const imaging::Volume& volume, double acquired_s, double arrived_s,
                                   const std::function<double()>& now_s) {
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
    if (writer_) writer_->AddTarget({acquired_s, arrived_s, std::max(arrived_s, now_s()), false, {}, {}, {}, det.confidence});
    return out;
  }
  if (!reference_axis_) reference_axis_ = det.axis.direction;
  try {
    ekf_.Process(acquired_s, det.target_mm.dot(*reference_axis_));
  } catch (const std::exception& e) {  // a measurement out of order or non-finite
    return fail(e);
  }
  out.measured = true;
  ++stats_.measured;
  out.published_s = std::max(arrived_s, now_s());
  if (ekf_.initialised() && publisher_) {
    link::TargetEstimateSample s;
    s.sequence_number = ++sequence_;
    s.acquisition_time_s = acquired_s + o_.link_offset_s;
    s.publication_time_s = out.published_s + o_.link_offset_s;
    s.target_mm = det.target_mm;
    s.axis = *reference_axis_;
    s.tip_mm = det.tip_mm;
    s.motion = ekf_.Motion();
    s.motion.t0_s += o_.link_offset_s;
    s.motion.valid_until_s += o_.link_offset_s;
    s.confidence = det.confidence;
    out.sequence = s.sequence_number;
    out.published = publisher_->Publish(s);
    if (out.published)
      ++stats_.published;
    else
      ++stats_.publish_failures;
  }
  if (writer_)
    writer_->AddTarget({acquired_s, arrived_s, out.published_s, true, det.target_mm, det.tip_mm, det.axis.direction,
                        det.confidence});
  return out;
}

}  // namespace echoservo::live
