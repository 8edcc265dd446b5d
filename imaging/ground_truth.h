// What a simulated volume really shows, for accuracy harnesses and recordings.
//
// All points in the volume's image frame (mm, MetaImage physical space: origin + direction
// · index·spacing), i.e. where an ideal detector working on the volume should report them
// — after the speed-of-sound scaling the scanner applies, not in the true world frame.
#pragma once

#include <Eigen/Core>
#include <optional>

namespace echoservo::imaging {

struct FrameGroundTruth {
  bool catheter_visible = false;
  Eigen::Vector3d axis_point_mm = Eigen::Vector3d::Zero();    // a point on the catheter axis
  Eigen::Vector3d axis_direction = Eigen::Vector3d::UnitZ();  // unit, pointing to the tip
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();           // guidewire tip
  bool target_visible = false;
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();  // where the axis meets tissue
  // When the volume was really acquired (s, the recording's clock), where its timestamp
  // says otherwise: a scanner that stamps volumes late (at sending; `echoservo scanner
  // --record --stamp-delay S`). Unset: the timestamp is the acquisition time.
  std::optional<double> acquisition_s;
};

}  // namespace echoservo::imaging
