// The EM tracker against the image: the rigid transform em_to_image (EM tracker frame →
// image frame) and the EM clock's offset (t_pipeline = t_em + em_time_offset_s), estimated
// from the same catheter tip seen by both: the EM sensor's positions (formats/em_log.h) and
// the tip the detector found in the volumes (targets.csv of a RUN, formats/run_record.h).
//
// Method: a grid over offsets with a closed-form rigid fit (Kabsch/Umeyama) at each, then a
// Ceres refinement of offset and pose together; with a known em_to_image only the offset.
// Refuses (std::invalid_argument saying why and what to record instead): too few samples or
// pairs, a tip that hardly moved or moved along a line (spread < min_spread_mm), a
// similarity scale far from 1 (inches read as mm, or the reverse). CheckAlignment then judges
// any alignment, estimated or given: registration residual, clock offset inside its window,
// motion correlation and overlap. Units: mm, s.
// Details: docs/report.md#alignment-clock-offset-and-emimage-registration
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "formats/em_log.h"

namespace echoservo::report {

// Timed 3D points, times strictly increasing (mm, s).
struct PointSeries {
  std::vector<double> t_s;
  std::vector<Eigen::Vector3d> p_mm;

  std::size_t size() const { return t_s.size(); }
  void Add(double t_s, const Eigen::Vector3d& p_mm);  // t_s after the last (asserted)
  // Linear interpolation between the samples around `t_s` when they are at most `max_gap_s`
  // apart; nullopt outside the series or across a longer gap.
  std::optional<Eigen::Vector3d> At(double t_s, double max_gap_s) const;
  double MedianPeriodS() const;  // NaN with fewer than 2 samples
};

// The valid samples of an EM log.
PointSeries ValidEmPoints(const formats::EmLog& log);

struct EmAlignmentOptions {
  // The offset is searched in offset_center_s ± max_offset_s; a NaN centre means the first
  // image time minus the first EM time (both recordings started together).
  double offset_center_s = std::numeric_limits<double>::quiet_NaN();
  double max_offset_s = 2.0;
  double grid_step_s = 0.0;  // 0: half the shorter median sample period (≥ window / 4000)
  double max_gap_s = 0.0;    // 0: 2.5 × the EM median period
  std::size_t min_pairs = 20;
  double min_spread_mm = 1.0;    // the tracked tip's second principal spread (SD)
  double huber_mm = 2.0;         // robust loss scale; 0: plain least squares
  double max_scale_error = 0.2;  // |similarity scale − 1| beyond this: a units error
  std::optional<Eigen::Isometry3d> em_to_image;  // known: estimate only the offset
  // Known (e.g. from a temporal calibration, `report --tracker-lag`): the offset is not
  // searched; the window is this value alone.
  std::optional<double> fixed_offset_s;
};

struct EmAlignment {
  Eigen::Isometry3d em_to_image = Eigen::Isometry3d::Identity();
  double em_time_offset_s = 0.0;  // t_pipeline = t_em + em_time_offset_s
  double residual_rms_mm = 0.0;   // |em_to_image·EM(t − offset) − image tip| over the pairs
  double residual_max_mm = 0.0;
  std::size_t pairs = 0;
  double coarse_offset_s = 0.0;   // the grid's best
  double similarity_scale = 1.0;  // image motion / EM motion at the grid's best
  Eigen::Vector3d spread_mm = Eigen::Vector3d::Zero();  // tracked tip principal SDs
  double offset_center_s = 0.0;                         // the search window actually used
  double max_offset_s = 0.0;
  double grid_step_s = 0.0;
  double max_gap_s = 0.0;             // EM interpolation never bridges a longer gap
  bool fixed_transform = false;       // em_to_image was given
  bool fixed_offset = false;          // fixed_offset_s was given (not searched)
  int iterations = 0;                 // Ceres
  std::vector<double> grid_offset_s;  // the coarse search, for a plot
  std::vector<double> grid_rms_mm;    // NaN where too few pairs
};

// `em` on the EM clock in the EM frame, `image_tip` on the pipeline clock in the image
// frame. Throws std::invalid_argument (see above) and for inconsistent options.
EmAlignment AlignEmToImage(const PointSeries& em, const PointSeries& image_tip,
                           const EmAlignmentOptions& options = {});

// Plausibility of an alignment, estimated or given: does the EM log belong to this run?
// Each check has a value, a bound and a message saying why it failed (with the numbers).
// Sources of the bounds: docs/report.md#plausibility-checks.
struct AlignmentCheck {
  std::string name;  // "registration", "clock offset", "motion correlation", "overlap"
  double value = 0.0;
  double bound = 0.0;
  bool passed = true;
  std::string message;  // why it failed; empty when it passed
};

struct AlignmentCheckLimits {
  // Registration residual RMS bound: the EM tracker's stated accuracy plus the detector's.
  // The seed's tracker, the Ascension (now NDI) 3D Guidance trakSTAR with a model 180
  // sensor, states a static position accuracy of 1.4 mm RMS (3D Guidance technical
  // specifications); an NDI Aurora states 0.48-0.70 mm RMS, so 1.4 mm covers both.
  static constexpr double kEmTrackerAccuracyMm = 1.4;
  // The Radon detector's tip error: every case of tests/tracking/radon_detector_test.cc is
  // asserted below 1 mm (worst measured 0.58 mm; p95 up to 0.92 mm in the accuracy
  // harness's wide poses, docs/detector.md).
  static constexpr double kDetectorTipAccuracyMm = 1.0;
  double max_registration_rms_mm = kEmTrackerAccuracyMm + kDetectorTipAccuracyMm;
  // Pearson correlation of the mapped EM tip and the tracked tip along the tracked tip's
  // principal axis. The right log correlates at s/√(s² + σ²) (s the motion's SD along the
  // axis, at least 1 mm or the alignment refuses; σ the per-axis residual): > 0.95 for
  // σ ≤ 0.3 mm. Another heartbeat's motion, with few independent beats, can correlate by
  // chance up to about 0.5; a still sensor correlates near 0.
  double min_motion_correlation = 0.7;
  // The pairs (EM interpolated at a tracked tip) must span this share of the tracked tips'
  // time span.
  double min_overlap_share = 0.5;
};

// Runs every check on `alignment` (from AlignEmToImage on the same `em` and `image_tip`).
std::vector<AlignmentCheck> CheckAlignment(const PointSeries& em, const PointSeries& image_tip,
                                           const EmAlignment& alignment,
                                           const AlignmentCheckLimits& limits = {});

// Rotation angle of a transform's linear part, degrees.
double RotationAngleDeg(const Eigen::Isometry3d& transform);

}  // namespace echoservo::report
