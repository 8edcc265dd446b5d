// Catheter-axis detector for 3D ultrasound volumes: a coarse-to-fine 3D Radon transform.
//
// For a direction d, projecting every voxel onto the plane ⟂ d and accumulating its
// intensity in a 2D histogram gives the line integrals of the volume along all lines
// parallel to d: the Radon (X-ray) transform for d. A straight bright catheter is a sharp
// peak of that histogram for d = its axis. The detector:
//   1. max-pools the volume ×4 (and ×2), subtracts the median (background) level;
//   2. ×4 level: scores a Fibonacci hemisphere of directions (TBB-parallel), each by its
//      best histogram peak's contrast against the ring around it (a line is a point in the
//      projection, a tissue surface seen edge-on a ridge: the ring's 2nd-highest sample is
//      subtracted, which cancels ridges but not one-sided reverberation tails);
//   3. refines the direction on a finer local grid at the ×2 level; among near-equal peaks
//      of that direction (parallel lines: reverberation comets deeper along the beam) takes
//      the shallowest (smallest image z);
//   4. full resolution: intensity-weighted iteratively-reweighted (Tukey) TLS line fit of
//      the voxels within a few mm of the line (tracking/line_fit.h FitLine);
//   5. tip: end of the bright run of the intensity profile along the axis, the end away
//      from where the line enters the volume; target: first tissue rise beyond the tip
//      (half-maximum crossing), along the axis;
//   6. confidence in [0, 1] from the peak's contrast against the distribution of the other
//      directions' scores and from the bright run's length; below `min_confidence`: not found.
// Tracking: with a previous axis, only a cone of directions around it and an offset window
// around it are searched; a full search follows when that gives a low confidence.
//
// Units: mm, rad, in the volume's image (physical) frame (imaging/volume.h).
#pragma once

#include <Eigen/Core>
#include <optional>

#include "imaging/volume.h"
#include "tracking/axis_profile.h"
#include "tracking/echo_axis_fit.h"
#include "tracking/line_fit.h"
#include "tracking/tube_check.h"

namespace echoservo::tracking {

struct RadonDetectorOptions {
  int coarse_factor = 4;              // first max-pooling factor (voxels), ≥ 2
  int coarse_directions = 2000;       // Fibonacci hemisphere size at the coarse level
  double fine_cone_rad = 0.08;        // refinement cone half-angle around the coarse best
  int fine_steps = 9;                 // refinement grid, fine_steps² directions per pass
  // Full-resolution axis fit (tracking/echo_axis_fit.h): fit cylinder, first-echo look-back
  // along the beam, and the catheter's outer diameters (the echo comes from the near wall).
  EchoAxisFitOptions fit;
  TubeCheckOptions tube;              // tube vs surface test (tracking/tube_check.h)
  EdgeOptions edge;                   // tip and target edges (tracking/axis_profile.h)
  double min_line_length_mm = 6.0;    // shorter bright runs are not a catheter
  double min_confidence = 0.5;        // below: not found
  double tracking_cone_rad = 0.17;    // tracking search cone half-angle (~10°)
  double tracking_window_mm = 6.0;    // tracking offset window around the previous axis
  // Lines whose point nearest the volume centre lies deeper (image z) than this fraction of
  // the volume's depth are ignored: far-field walls (tank floor) make bright strips there.
  double max_depth_fraction = 1.0;
  double max_spacing_ratio = 4.0;     // larger max/min spacing ratio: std::invalid_argument

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

struct CatheterDetection {
  bool found = false;
  Line3 axis;                                        // direction points to the tip
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  bool target_found = false;
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  double confidence = 0.0;                           // [0, 1]
  double line_length_mm = 0.0;                       // bright run length along the axis
  bool tracked = false;                              // result of the tracking search
  double tubularity = 0.0;  // tracking/tube_check.h: ≈ 1 tube, ≈ 0 line within a surface
  double peak_z = 0.0;  // robust z-score of the Radon peak among its histogram's lines
};

class RadonDetector {
 public:
  explicit RadonDetector(RadonDetectorOptions options = {});

  // Full search, stateless. Throws std::invalid_argument for a volume it cannot judge
  // (too anisotropic); returns found = false for volumes without a credible line (tiny,
  // constant, saturated, catheter-free).
  CatheterDetection Detect(const imaging::Volume& volume) const;

  // Searches near `previous` (tracking) and falls back to the full search when the
  // tracked result's confidence is below min_confidence.
  CatheterDetection Detect(const imaging::Volume& volume, const Line3& previous) const;

  // Stateful tracking over a stream: uses the last found axis, full search otherwise.
  CatheterDetection Track(const imaging::Volume& volume);
  void Reset() { previous_.reset(); }

  const RadonDetectorOptions& options() const { return options_; }

 private:
  CatheterDetection Run(const imaging::Volume& volume, const Line3* previous) const;

  RadonDetectorOptions options_;
  std::optional<Line3> previous_;
};

}  // namespace echoservo::tracking
