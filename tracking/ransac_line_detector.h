// RANSAC line detector: the usual peer baseline the Radon detector (tracking/radon_detector.h)
// is measured against (tracking/detector_accuracy.h, `echoservo bench detect`).
//
// Threshold, surface removal, local two-point RANSAC scored against a shell, TLS refit and the
// longest inlier run; the tip at its end away from where the line enters the volume, the target
// at the first bright sample ahead of it. In: a Volume. Out: the same CatheterDetection as the
// Radon detector, in the volume's image frame (mm). Deterministic: the RNG is seeded from the
// options. Errors: Validate throws std::invalid_argument naming the field.
// Details: docs/detector.md#ransac-baseline-trackingransac_line_detectorh
#pragma once

#include <cstdint>

#include "imaging/volume.h"
#include "tracking/radon_detector.h"

namespace echoservo::tracking {

struct RansacLineDetectorOptions {
  double threshold_quantile = 0.99;  // of the non-zero voxel values, [0.5, 1)
  double threshold_mad_k = 3.0;      // T ≥ median + k·1.4826·MAD, ≥ 0
  // Surface removal before RANSAC: bright voxels binned into cells of component_cell_mm,
  // 26-connected cells form components, and a component whose middle principal standard
  // deviation exceeds max_component_sigma_mm (a surface: the tank floor, a bone) is dropped;
  // a line or a tube keeps two small ones. 0: off.
  double max_component_sigma_mm = 2.0;  // ≥ 0
  double component_cell_mm = 2.0;       // > 0
  int max_points = 4000;                // random subset used to score hypotheses, ≥ 100
  int iterations = 1500;                // RANSAC hypotheses, ≥ 1
  double inlier_radius_mm = 1.5;        // > 0 (the sheath is 2.5 mm across)
  // The two sample points of a hypothesis lie min..max apart (local sampling, NAPSAC: the
  // second point is drawn near the first, so a structure holding a few % of the bright voxels
  // still gets hypotheses within a few thousand iterations).
  double min_sample_separation_mm = 5.0;   // ≥ 0
  double max_sample_separation_mm = 20.0;  // > min_sample_separation_mm
  // Score = inliers − shell_penalty × points in the shell r ≤ d < 2r around the line, ≥ 0.
  // 1 cancels surfaces (a line lying in a bright plane has as many shell points as inliers)
  // and keeps thin tubes; 0 is the plain inlier count. (Plain RANSAC, without this and the
  // surface removal, locks onto the saturated tank floor in every simulated volume.)
  double shell_penalty = 1.0;
  double max_gap_mm = 3.0;          // inlier runs along the line split at larger gaps, > 0
  int min_inliers = 30;             // fewer: not found, ≥ 2
  double min_line_length_mm = 6.0;  // shorter runs: not found, ≥ 0
  double target_start_mm = 2.0;     // target search starts this far beyond the tip, ≥ 0
  double target_search_mm = 40.0;   // and ends this far, > target_start_mm
  double target_fraction = 0.25;    // of the line level, (0, 1]
  std::uint64_t seed = 1;

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

class RansacLineDetector {
 public:
  explicit RansacLineDetector(RansacLineDetectorOptions options = {});

  // Found = false for volumes smaller than 8 voxels on an axis, without voxels above the
  // threshold, or whose best line has fewer than min_inliers inliers or a run shorter than
  // min_line_length_mm. confidence = min(1, inliers / (4 · min_inliers)) ·
  // min(1, run length / (2 · min_line_length_mm)); peak_z and tracked stay 0 / false.
  CatheterDetection Detect(const imaging::Volume& volume) const;

  const RansacLineDetectorOptions& options() const { return options_; }

 private:
  RansacLineDetectorOptions options_;
};

}  // namespace echoservo::tracking
