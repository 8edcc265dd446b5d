// Where the catheter ends and what it points at, from intensity profiles along its axis.
//
// FindTip: the end of the brightest run along the axis (most echo above its threshold: the
// wire outshines tissue by 20–40 dB) away from where it enters the scanned region, its edge
// located in echo amplitude on first echoes only (a guidewire's reverberation tail lies
// beyond its tip). FindTarget: the first tissue surface beyond the
// tip, from a least-squares fit of its echo and backscatter, on the axis and on rays beside
// the tip (the surface extends sideways beyond the catheter, the tip does not): down to
// contact (gap 0, flagged), and a target hugging the tip only when the surface around the
// tip confirms it.
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
  // Target search beside the tip (FindTarget): rays parallel to the axis at this radius
  // (beyond the catheter's), (0, 20] mm, starting this far before the tip, [3, 30] mm (the
  // first 4 mm are their background; FindTip's tip can lie behind a 3 mm tissue).
  double lateral_radius_mm = 3.5;
  double lateral_back_mm = 10.0;
  // Gaps below close_gap_mm are taken from the surface beside the tip (the tip's echo and
  // the tissue's merge on the axis), (0, 20] mm; at or below contact_gap_mm the tip touches
  // the tissue (contact, gap 0), [0, close_gap_mm); an axial target within doubt_gap_mm of
  // the tip needs the surface beside the tip to confirm it, [0, close_gap_mm).
  double close_gap_mm = 4.0;
  double contact_gap_mm = 0.3;
  double doubt_gap_mm = 1.0;
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
  bool contact = false;         // the tip touches the tissue (gap 0)
  double gap_mm = 0.0;          // from the tip to the target along the axis, ≥ 0
  double indentation_mm = 0.0;  // in contact: the tip this far past the surface around it
  // The tip, re-located before the tissue when FindTip's bright run went on through it
  // (within ~2 mm of tissue); else the TipEstimate's.
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  // Where the axis meets the tissue's surface; in contact the surface around the tip, which
  // lies behind the tip by indentation_mm when the tip presses into the tissue.
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
};

TargetEstimate FindTarget(const imaging::Volume& volume, const TipEstimate& tip, double background,
                          const EdgeOptions& edge);

}  // namespace echoservo::tracking
