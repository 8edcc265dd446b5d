// Exhaustive full-resolution Radon reference: the strongest line of a volume's 3D Radon
// transform searched without the fast detector's shortcuts (no max-pooling, no coarse level,
// no offset window), the reference the fast RadonDetector (tracking/radon_detector.h) must
// agree with (tracking/detector_accuracy.h, `echoservo bench detect --exhaustive`).
//
// Built on tracking/radon_transform.h: MakeRadonLevel(volume, 1, ·) keeps every voxel above
// the median non-zero value, weighted by (value − median)²; histogram bins are the voxel size
// (cube root of the voxel volume). Directions, all at full resolution:
//   1. a Fibonacci hemisphere of `hemisphere_directions` (4000: ≈ 2.3° apart);
//   2. around each of the `refine_candidates` best hemisphere directions (at least
//      `candidate_separation_rad` apart), a DirectionCone of ±`cone_half_rad` (0.04 rad ≈ 2.3°,
//      covering a hemisphere cell) on a `cone_steps`² grid (17²: 0.005 rad ≈ 0.29° apart);
//   3. around the best so far, ±`fine_half_rad` (0.005 rad) on a `fine_steps`² grid (11²:
//      0.001 rad ≈ 0.06° apart).
// About 5000 histograms per volume: seconds, not milliseconds (a reference, not a detector).
// The peak offset is sub-bin (parabola, radon_transform.h). As in the fast detector, among
// peaks of the best direction scoring ≥ `parallel_peak_ratio` of the best, the shallowest
// (smallest image z, at most `parallel_max_shallower_mm` shallower) is taken: reverberation
// comet tails are parallel lines deeper along the beam.
// Lines whose point nearest the volume centre lies in the deepest 15 % of the volume are
// ignored (`max_depth_fraction` 0.85, MakeRadonLevel): at full resolution the water tank's
// floor, a one-voxel-thick saturated plane with stripes, otherwise wins.
// Only the axis is reported (no tip or target): the fast detector's tip and target stages are
// internal to it. The line is the Radon peak itself, with no axis fit: on simulated catheters
// it follows the echo centroid (sheath near and far wall, wire, comet tail) and is 0.7–3.6°
// off the true axis; on a synthetic bright line the voxel lattice limits it to ≈ 0.1–1°
// (bins = the voxel size). It checks that the fast search finds the same line, not the
// fast detector's sub-degree fit.
//
// Units: mm, rad, in the volume's image (physical) frame.
#pragma once

#include "imaging/volume.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

struct ExhaustiveRadonOptions {
  int hemisphere_directions = 4000;      // ≥ 16
  int refine_candidates = 3;             // ≥ 1
  double candidate_separation_rad = 0.1; // > 0
  double cone_half_rad = 0.04;           // (0, 0.5]
  int cone_steps = 17;                   // ≥ 2
  double fine_half_rad = 0.005;          // (0, 0.5]
  int fine_steps = 11;                   // ≥ 2
  double max_depth_fraction = 0.85;      // (0, 1]: deeper lines ignored (MakeRadonLevel)
  double parallel_peak_ratio = 0.6;      // (0, 1]
  double parallel_max_shallower_mm = 15.0;  // ≥ 0

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

struct ExhaustiveRadonResult {
  bool found = false;     // false: no voxel above the background, or no peak
  Line3 axis;             // direction sign arbitrary
  double score = 0.0;     // peak contrast (weight units)
  int directions = 0;     // histograms computed
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
AxisAgreement CompareAxes(const Line3& detected, const Eigen::Vector3d& point_mm, const Line3& reference);

}  // namespace echoservo::tracking
