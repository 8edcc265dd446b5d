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

#include "formats/parameter_spec.h"
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

// The target profile's tunable parameters (formats/parameter_spec.h), and the scanner's
// dynamic range its edges share with the detector: declared once, read by the defaults below,
// by RadonDetectorOptions::Validate and by the registry (live/pipeline_parameters.h).
namespace params {
inline constexpr formats::ParameterSpec kDynamicRangeDb{
    "detector.dynamic_range_db",
    "dB",
    formats::ParameterKind::kReal,
    10,
    120,
    50.0,
    "the scanner's display dynamic range (0-255 spans it): edges and the tube check work in "
    "echo amplitude; clinical 3D scanners use 30-80 dB"};
inline constexpr formats::ParameterSpec kEdgeFraction{
    "target.edge_fraction",
    "1",
    formats::ParameterKind::kReal,
    0.05,
    0.95,
    0.5,
    "tip and target edges at this fraction between background and echo level, in echo "
    "amplitude (0.5: the half-amplitude point of a symmetric blur)"};
inline constexpr formats::ParameterSpec kTipFirstEchoMm{
    "target.tip_first_echo_mm",
    "mm",
    formats::ParameterKind::kReal,
    0,
    20,
    3.0,
    "the tip's edge uses first echoes only: a brighter sample this close nearer the probe "
    "marks a reverberation tail; 0: off"};
inline constexpr formats::ParameterSpec kLateralRadiusMm{
    "target.lateral_radius_mm",
    "mm",
    formats::ParameterKind::kReal,
    0.5,
    20,
    3.5,
    "the target search's rays beside the tip run at this radius from the axis (beyond the "
    "catheter's own echo)"};
inline constexpr formats::ParameterSpec kCloseGapMm{
    "target.close_gap_mm",
    "mm",
    formats::ParameterKind::kReal,
    1.5,
    20,
    4.0,
    "gaps below this come from the surface beside the tip (the tip's and the tissue's echoes "
    "merge on the axis: about the axial resolution, >= 1.5 mm)"};
inline constexpr formats::ParameterSpec kContactGapMm{
    "target.contact_gap_mm",
    "mm",
    formats::ParameterKind::kReal,
    0,
    2,
    0.3,
    "at or below this gap the tip touches the tissue (contact, gap 0); less than "
    "target.close_gap_mm"};
}  // namespace params

struct EdgeOptions {
  double dynamic_range_db =
      params::kDynamicRangeDb.default_value;  // the scanner's display dynamic range, (0, 120]
  double edge_fraction =
      params::kEdgeFraction
          .default_value;  // edge at this fraction between background and level, (0, 1)
  // The tip's edge is located on first echoes only: a sample with a brighter one up to this
  // far nearer the transducer along its beam is a reverberation tail, not the wire [0, 50)
  // mm; 0: off. See FindTip.
  double tip_first_echo_mm = params::kTipFirstEchoMm.default_value;
  // Target search beside the tip (FindTarget): rays parallel to the axis at this radius
  // (beyond the catheter's), (0, 20] mm, starting this far before the tip, [3, 30] mm (the
  // first 4 mm are their background; FindTip's tip can lie behind a 3 mm tissue).
  double lateral_radius_mm = params::kLateralRadiusMm.default_value;
  double lateral_back_mm = 10.0;
  // Gaps below close_gap_mm are taken from the surface beside the tip (the tip's echo and
  // the tissue's merge on the axis), (0, 20] mm; at or below contact_gap_mm the tip touches
  // the tissue (contact, gap 0), [0, close_gap_mm); an axial target within doubt_gap_mm of
  // the tip needs the surface beside the tip to confirm it, [0, close_gap_mm).
  double close_gap_mm = params::kCloseGapMm.default_value;
  double contact_gap_mm = params::kContactGapMm.default_value;
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
