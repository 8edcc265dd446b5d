// The EM tracker against the image: the rigid transform em_to_image (EM tracker frame →
// image frame) and the EM clock's offset (t_pipeline = t_em + em_time_offset_s), estimated
// from the same catheter tip seen by both: the EM sensor's positions (hw/io/em_log.h) and
// the tip the detector found in the volumes (targets.csv of a RUN, hw/io/run_record.h).
//
// Method: a grid over offsets with a closed-form rigid fit (Kabsch/Umeyama) at each, then a
// Ceres refinement of offset and pose together; with a known em_to_image only the offset.
// Refuses (std::invalid_argument saying why and what to record instead): too few samples or
// pairs, a tip that hardly moved or moved along a line (spread < min_spread_mm), a
// similarity scale far from 1 (inches read as mm, or the reverse). Units: mm, s.
// Details: docs/report.md#alignment-clock-offset-and-emimage-registration
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <limits>
#include <optional>
#include <vector>

#include "hw/io/em_log.h"

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
PointSeries ValidEmPoints(const hw::EmLog& log);

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
  bool fixed_transform = false;       // em_to_image was given
  int iterations = 0;                 // Ceres
  std::vector<double> grid_offset_s;  // the coarse search, for a plot
  std::vector<double> grid_rms_mm;    // NaN where too few pairs
};

// `em` on the EM clock in the EM frame, `image_tip` on the pipeline clock in the image
// frame. Throws std::invalid_argument (see above) and for inconsistent options.
EmAlignment AlignEmToImage(const PointSeries& em, const PointSeries& image_tip,
                           const EmAlignmentOptions& options = {});

// Rotation angle of a transform's linear part, degrees.
double RotationAngleDeg(const Eigen::Isometry3d& transform);

}  // namespace echoservo::report
