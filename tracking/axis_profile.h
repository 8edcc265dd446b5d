// Where the catheter ends and what it points at, from intensity profiles along its axis.
//
// Tip: the profile along the axis is the maximum over a small disc ⟂ the axis (so a
// sub-voxel axis error does not dim it), smoothed over 1 mm. The longest bright run (above
// background + 30 % of the profile's 90th percentile, gaps ≤ 2 mm) is the catheter; its end
// nearer the edge of the scanned region is where it enters, the other end is the tip, placed
// where the profile drops below background + `tip_fraction` of its level over the last 3 mm.
// That edge is then located again, within 3 mm of it, on a profile of first echoes only
// (`tip_first_echo_mm`): a metal wire rings, and its comet tail runs along the beam, deeper,
// from every point of the wire that a beam hits — from its very end too. Where the axis is
// tilted towards depth the beam has a component along it (sin of the angle), so the tail of
// the wire's last echoes lies beyond the tip along the axis and within the profile's disc: a
// half-amplitude edge of all echoes sits 0.1–0.3 mm beyond the tip. A tail sample has its own
// wire echo nearer the transducer along its beam, brighter (each ring is weaker): the same
// first-echo rule as the axis fit (tracking/echo_axis_fit.h) leaves the tails out and keeps
// the wire's near-wall echo, whose blur by the point-spread function is symmetric.
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
  // The tip's edge is located on first echoes only: a sample with a brighter one up to this
  // far nearer the transducer along its beam is a reverberation tail, not the wire [0, 50)
  // mm; 0: off. See FindTip.
  double tip_first_echo_mm = 3.0;
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
