// Where the catheter ends and what it points at, from intensity profiles along its axis.
//
// FindTip: the end of the longest bright run along the axis away from where it enters the
// scanned region, its edge located in echo amplitude on first echoes only (a guidewire's
// reverberation tail lies beyond its tip). FindTarget: the first tissue surface beyond the
// tip, from a least-squares fit of its echo and backscatter.
// In: a Volume, the axis and the background voxel value. Out: points in the volume's image
// frame (mm); display values map to echo amplitude over dynamic_range_db (dB).
// Details: docs/detector.md#algorithm (steps 5 and 6)
#pragma once

#include <Eigen/Core>

#include "imaging/volume.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

// Edges are located in echo amplitude, not in display values: volumes hold log-compressed
// values, 0–255 over the scanner's dynamic range, and a blurred step's half-amplitude point
// (where a symmetric point-spread function puts the true edge) is far from its half-display
// point.
// Log-compressed display value (0–255 spanning `dynamic_range_db`) → echo amplitude, relative
// to the amplitude displayed as 0.
double EchoAmplitude(double display, double dynamic_range_db);

struct EdgeOptions {
  double dynamic_range_db = 50.0;  // the scanner's display dynamic range, (0, 120]
  double edge_fraction = 0.5;      // edge at this fraction between background and level, (0, 1)
  // The tip's edge is located on first echoes only: a sample with a brighter one up to this
  // far nearer the transducer along its beam is a reverberation tail, not the wire [0, 50)
  // mm; 0: off. See FindTip.
  double tip_first_echo_mm = 3.0;
};

struct TipEstimate {
  bool found = false;
  Line3 axis;  // direction oriented towards the tip
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  double line_length_mm = 0.0;  // the bright run's length
  double line_level = 0.0;      // profile level near the tip (voxel value)
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
