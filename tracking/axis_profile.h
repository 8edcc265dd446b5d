// Where the catheter ends and what it points at, from intensity profiles along its axis.
//
// Tip: the profile along the axis is the maximum over a small disc ⟂ the axis (so a
// sub-voxel axis error does not dim it), smoothed over 1 mm. The longest bright run (above
// background + 30 % of the profile's 90th percentile, gaps ≤ 2 mm) is the catheter; its end
// nearer the edge of the scanned region is where it enters, the other end is the tip, placed
// where the profile drops below background + `tip_fraction` of its level over the last 3 mm.
// Target: forward from 2 mm beyond the tip, the profile is the mean over a 0.75 mm disc.
// Its first rise above the local background (median of the next 4 mm) by max(12, 10 % of
// the line level, 5 × the background's robust spread — blood speckles too) marks tissue; the
// surface is then located by a least-squares fit, in echo amplitude, of background + the
// interface's echo (the pulse envelope) + the tissue's backscatter from the surface on (the
// envelope's integral), with the blur fitted too: a bright tissue interior makes the first
// echo's peak — and a thick tissue's far wall — useless as the surface.
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
// Log-compressed display value (0–255 spanning `dynamic_range_db`) → echo amplitude, relative
// to the amplitude displayed as 0.
double EchoAmplitude(double display, double dynamic_range_db);

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
