// Catheter-axis detector for 3D ultrasound volumes, a coarse-to-fine 3D Radon transform: the
// catheter axis, the guidewire tip and the target (the first tissue surface ahead of the tip).
//
// In: a Volume (imaging/volume.h); for tracking, the previous axis or detection. Out: a
// CatheterDetection in the volume's image frame (mm, rad): axis (direction to the tip), tip_mm,
// target_mm, confidence in [0, 1]; found only at confidence ≥ min_confidence. Tracking searches
// a cone and an offset window around the previous axis, reusing its SceneBaseline, and falls
// back to a full search on low confidence; Track keeps the last found detection (Reset).
// Errors: Detect throws std::invalid_argument for a volume too anisotropic to judge
// (max_spacing_ratio); Validate throws it naming a bad option.
// Notation: docs/architecture.md#units-frames-and-naming
// Details: docs/detector.md#algorithm
#pragma once

#include <Eigen/Core>
#include <optional>

#include "imaging/volume.h"
#include "tracking/axis_profile.h"
#include "tracking/echo_axis_fit.h"
#include "tracking/line_fit.h"
#include "tracking/radon_transform.h"
#include "tracking/tube_check.h"

namespace echoservo::tracking {

// The detector's own tunable parameters (formats/parameter_spec.h); its axis fit's and edges'
// are declared beside them (tracking/echo_axis_fit.h, tracking/axis_profile.h).
namespace params {
inline constexpr formats::ParameterSpec kCoarseDirections{
    "detector.coarse_directions",
    "1",
    formats::ParameterKind::kInteger,
    100,
    20000,
    2000,
    "directions of the coarse Radon search's hemisphere (angular step ~sqrt(2pi/N): 0.18 rad at "
    "200, 0.018 rad at 20000); the detector's main cost"};
inline constexpr formats::ParameterSpec kMinConfidence{
    "detector.min_confidence",
    "1",
    formats::ParameterKind::kReal,
    0,
    1,
    0.5,
    "detections below this confidence are not found (tracking falls back to a full search)"};
inline constexpr formats::ParameterSpec kTrackingConeRad{
    "detector.tracking_cone_rad",
    "rad",
    formats::ParameterKind::kReal,
    0.02,
    1.0,
    0.17,
    "tracking searches this half-angle around the previous axis (the catheter's turn between "
    "volumes); 1 rad is nearly a full search"};
inline constexpr formats::ParameterSpec kTrackingWindowMm{
    "detector.tracking_window_mm",
    "mm",
    formats::ParameterKind::kReal,
    0.5,
    30,
    6.0,
    "tracking searches offsets this far around the previous axis (the catheter's sideways "
    "motion between volumes)"};
}  // namespace params

struct RadonDetectorOptions {
  int coarse_factor = 4;  // first max-pooling factor (voxels), ≥ 2
  int coarse_directions = static_cast<int>(
      params::kCoarseDirections.default_value);  // Fibonacci hemisphere size at the coarse level
  // The coarse search over the hemisphere (tracking/radon_transform.h
  // SearchDirectionsCoarseToFine): every 5th direction (~0.13 rad apart at 2000; a direction
  // lies within ~0.08 rad of one), then the others within 0.14 rad of the 8 best. Measured on
  // every `bench detect` class (8 volumes each, seeds 7 and 11): the same detections and
  // errors as every 4th within 0.17 rad of the 16 best (and every 2nd within 0.12 rad), the
  // search at ~75 % of that one's time.
  CoarseToFineOptions hemisphere_search{5, 8, 0.14};
  double fine_cone_rad = 0.08;  // refinement cone half-angle around the coarse best
  int fine_steps = 9;           // refinement grid, fine_steps² directions per pass
  // Full-resolution axis fit (tracking/echo_axis_fit.h): fit cylinder, first-echo look-back
  // along the beam, and the catheter's outer diameters (the echo comes from the near wall).
  EchoAxisFitOptions fit;
  TubeCheckOptions tube;            // tube vs surface test (tracking/tube_check.h)
  EdgeOptions edge;                 // tip and target edges (tracking/axis_profile.h)
  double min_line_length_mm = 6.0;  // shorter bright runs are not a catheter
  double min_confidence = params::kMinConfidence.default_value;  // below: not found
  // tracking search cone half-angle (~10°)
  double tracking_cone_rad = params::kTrackingConeRad.default_value;
  // tracking offset window around the previous axis
  double tracking_window_mm = params::kTrackingWindowMm.default_value;
  // Lines whose point nearest the volume centre lies deeper (image z) than this fraction of
  // the volume's depth are ignored: far-field walls (tank floor) make bright strips there.
  double max_depth_fraction = 1.0;
  double max_spacing_ratio = 4.0;  // larger max/min spacing ratio: std::invalid_argument
  // The Radon levels keep only the cells brighter than their background by this fraction of
  // the range up to their bright end (tracking/radon_transform.h MakeRadonLevel; 0: every
  // cell above the background): faint speckle is most of a tissue volume's cells, costs a
  // splat per cell and direction, and weighs little ((value − background)²).
  double level_min_contrast = 0.125;
  // A full search whose best line is not a catheter (tube check, length) tries up to this
  // many directions in all, each at least candidate_separation_rad from those tried.
  int max_candidates = 3;
  double candidate_separation_rad = 0.35;  // ~20°
  // The beams, when the caller knows them (CLI --probe-apex, --beam-direction); otherwise the
  // volume's (BeamGeometry::FromVolume: unknown without an image-to-probe transform). Unknown
  // beams: the symmetric centre-line axis fit, the tube check judges the ribbon from the
  // cross-section, and the tip edge uses all echoes (docs/detector.md#beam-geometry).
  std::optional<BeamGeometry> beams;
  // Unknown beams: when the catheter's cross-sections show a reverberation ribbon (tube_check.h
  // RibbonDirection), fit again with parallel beams along it (the near-wall model and the
  // first-echo rule then apply); false: the symmetric centre-line fit always.
  bool infer_beams_from_ribbon = true;

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

// What tracking reuses from the frame it started from (a full search): the scene's intensity
// levels and the spread of line scores over the hemisphere (the confidence's baseline).
// They describe the scene and the scanner's gain, change little from frame to frame, and
// measuring them takes a pass over the whole volume and a search of the hemisphere — far
// more than the rest of a tracked frame.
struct SceneBaseline {
  bool valid = false;
  double voxel_background = 0.0;  // median non-zero voxel value
  LevelThresholds coarse, fine;   // the Radon levels' (tracking/radon_transform.h)
  // Median and median absolute deviation of the best line scores of the hemisphere's
  // directions (coarse level).
  double score_median = 0.0, score_mad = 0.0;
  // The statistics leave out the directions whose best line meets the detected catheter (its
  // own echo seen from the side: radon_detector.cc RestOfScene); a z-score against them then
  // counts only for a long bright run.
  bool scores_without_line = false;
  // Unknown beams: the parallel beams a full search inferred from the catheter's
  // reverberation ribbon (RadonDetectorOptions::infer_beams_from_ribbon). The probe does not
  // turn between volumes, so tracking fits with them at once, without the symmetric fit and
  // the ribbon search that found them.
  std::optional<BeamGeometry> inferred_beams;
};

struct CatheterDetection {
  bool found = false;
  Line3 axis;  // direction points to the tip
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  bool target_found = false;
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  // The tip touches the target's tissue (gap 0); target_mm is then the surface around the
  // tip, behind it by target_indentation_mm when the tip presses into the tissue.
  bool contact = false;
  double target_gap_mm = 0.0;          // tip to target along the axis, ≥ 0
  double target_indentation_mm = 0.0;  // ≥ 0
  double confidence = 0.0;             // [0, 1]
  double line_length_mm = 0.0;         // bright run length along the axis
  bool tracked = false;                // result of the tracking search
  double tubularity = 0.0;  // tracking/tube_check.h: ≈ 1 tube, ≈ 0 line within a surface
  double peak_z = 0.0;      // robust z-score of the Radon peak among its histogram's lines
  SceneBaseline baseline;   // the statistics this result used (valid once the search ran)
};

class RadonDetector {
 public:
  explicit RadonDetector(RadonDetectorOptions options = {});

  // Full search, stateless. Throws std::invalid_argument for a volume it cannot judge
  // (too anisotropic); returns found = false for volumes without a credible line (tiny,
  // constant, saturated, catheter-free).
  CatheterDetection Detect(const imaging::Volume& volume) const;

  // Searches near `previous` (tracking) and falls back to the full search when the
  // tracked result's confidence is below min_confidence. The scene's statistics are measured
  // on `volume` (a pass over all of it and a sparse hemisphere search).
  CatheterDetection Detect(const imaging::Volume& volume, const Line3& previous) const;

  // The same near previous.axis, reusing previous.baseline (when valid): only the region
  // around the axis is read. A full search when `previous` was not found.
  CatheterDetection Detect(const imaging::Volume& volume, const CatheterDetection& previous) const;

  // Stateful tracking over a stream: from the last found detection, full search otherwise.
  CatheterDetection Track(const imaging::Volume& volume);
  void Reset() { previous_.reset(); }

  const RadonDetectorOptions& options() const { return options_; }

 private:
  CatheterDetection Run(const imaging::Volume& volume, const Line3* previous,
                        const SceneBaseline* scene) const;
  // The fine level's direction refinement: `passes` grids of fine_steps² directions, the
  // first within cone_rad, each next one (fine_steps − 1)/2 times narrower.
  struct FineSearch {
    double cone_rad;
    int passes;
    int steps;  // the grid's directions per side, odd
  };
  // Refines one coarse line (direction and peak) and judges it: axis fit, tip, target, tube
  // check, confidence. `rest`: the scene's line scores without those meeting this line (a
  // full search), a second z-score for a long bright run.
  CatheterDetection EvaluateLine(const imaging::Volume& volume, const RadonLevel& coarse,
                                 const RadonLevel& fine_level, const Eigen::Vector3d& direction,
                                 const RadonPeak& coarse_peak, const FineSearch& fine,
                                 const RadonWindow* window, double background,
                                 const SceneBaseline& scene,
                                 const SceneBaseline* rest = nullptr) const;

  RadonDetectorOptions options_;
  std::optional<CatheterDetection> previous_;
};

}  // namespace echoservo::tracking
