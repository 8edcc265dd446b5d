// Exhaustive full-resolution Radon reference: the strongest line of a volume's 3D Radon
// transform searched without the fast detector's shortcuts, the reference the fast
// RadonDetector (tracking/radon_detector.h) must agree with (tracking/detector_accuracy.h).
//
// In: a Volume. Out: the axis only (no tip or target) in the volume's image frame (mm,
// direction sign arbitrary): the raw Radon peak, with no axis fit, so 0.7–3.6° off the true
// axis on simulated catheters. About 5000 histograms: seconds per volume, not milliseconds.
// Errors: std::invalid_argument for invalid options (Validate names the field); a volume
// under 8 voxels on an axis gives found = false.
// Details: docs/detector.md#exhaustive-reference-trackingexhaustive_radonh
#pragma once

#include "imaging/volume.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

struct ExhaustiveRadonOptions {
  int hemisphere_directions = 4000;         // ≥ 16
  int refine_candidates = 3;                // ≥ 1
  double candidate_separation_rad = 0.1;    // > 0
  double cone_half_rad = 0.04;              // (0, 0.5]
  int cone_steps = 17;                      // ≥ 2
  double fine_half_rad = 0.005;             // (0, 0.5]
  int fine_steps = 11;                      // ≥ 2
  double max_depth_fraction = 0.85;         // (0, 1]: deeper lines ignored (MakeRadonLevel)
  double parallel_peak_ratio = 0.6;         // (0, 1]
  double parallel_max_shallower_mm = 15.0;  // ≥ 0

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

struct ExhaustiveRadonResult {
  bool found = false;  // false: no voxel above the background, or no peak
  Line3 axis;          // direction sign arbitrary
  double score = 0.0;  // peak contrast (weight units)
  int directions = 0;  // histograms computed
  double bin_mm = 0.0;
};

// Throws std::invalid_argument for invalid options; a volume smaller than 8 voxels on an
// axis gives found = false.
ExhaustiveRadonResult ExhaustiveRadonAxis(const imaging::Volume& volume,
                                          const ExhaustiveRadonOptions& options = {});

// How far a detected axis is from a reference axis: the angle between them (deg, sign of the
// directions ignored) and the distance from `point_mm` (the detected tip) to the reference line.
struct AxisAgreement {
  double angle_deg = 0.0;
  double offset_mm = 0.0;
};
AxisAgreement CompareAxes(const Line3& detected, const Eigen::Vector3d& point_mm,
                          const Line3& reference);

}  // namespace echoservo::tracking
