#include "imaging/sim/catheter_scene.h"

#include <numbers>

namespace echoservo::imaging::sim {

void PlaceCatheterScene(const CatheterScenePose& pose, SimulatedScannerOptions& o) {
  constexpr double kDeg = std::numbers::pi / 180.0;
  constexpr double kAnnulusBeyondTipMm = 15.0;
  const double tip_from_base_mm =
      o.catheter_geometry.sheath_length_mm + o.catheter_geometry.wire_protrusion_mm;
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
  base.linear() = (Eigen::AngleAxisd(pose.yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd((90.0 - pose.tilt_deg) * kDeg, Eigen::Vector3d::UnitY()))
                      .toRotationMatrix();
  const Eigen::Vector3d dir = base.linear().col(2);
  base.translation() = Eigen::Vector3d(pose.lateral_mm, 0, pose.depth_mm) - tip_from_base_mm * dir;
  o.catheter_pose.base_to_world = base;
  o.catheter_pose.advance_mm = pose.advance_mm;
  Eigen::Isometry3d annulus = base;
  annulus.translation() += (tip_from_base_mm + kAnnulusBeyondTipMm) * dir;
  o.annulus_to_world = annulus;
}

}  // namespace echoservo::imaging::sim
