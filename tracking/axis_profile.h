// Where the catheter ends and what it points at, from intensity profiles along its axis.
//
// Tip: the profile along the axis is the maximum over a small disc ⟂ the axis (so a
// sub-voxel axis error does not dim it), smoothed over 1 mm. The longest bright run (above
// background + 30 % of the profile's 90th percentile, gaps ≤ 2 mm) is the catheter; its end
// nearer the edge of the scanned region is where it enters, the other end is the tip, placed
// where the profile drops below background + `tip_fraction` of its level over the last 3 mm.
// Target: forward from 2 mm beyond the tip, the first rise of the profile (disc radius
// 1.5 mm) above its local background, followed to its peak; the target is the half-maximum
// crossing before that peak — the tissue surface the catheter points at.
//
// Units: mm in the volume's image frame.
#pragma once

#include <Eigen/Core>

#include "imaging/volume.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

// Edges are located in echo amplitude, not in display values: volumes hold log-compressed
// values, 0–255 over the scanner's dynamic range, and a blurred step's half-amplitude point
// (where a symmetric point-spread function puts the true edge) is far from its half-display
// point. 
struct EdgeOptions {
  double dynamic_range_db = 50.0;  // the scanner's display dynamic range, (0, 120]
  double edge_fraction = 0.5;      // edge at this fraction between background and level, (0, 1)
};

struct TipEstimate {
  bool found = false;
  Line3 axis;                      // direction oriented towards the tip
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  double line_length_mm = 0.0;     // the bright run's length
  double line_level = 0.0;         // profile level near the tip (voxel value)
};

// `background`: the volume's background voxel value.
TipEstimate FindTip(const imaging::Volume& volume, const Line3& axis, double background,
                    const EdgeOptions& edge);

struct TargetEstimate {
  bool found = false;
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
};

TargetEstimate FindTarget(const imaging::Volume& volume, const TipEstimate& tip, double background,
                          const EdgeOptions& edge);

}  // namespace echoservo::tracking
