// Full-resolution fit of the catheter axis to its echoes, modelling where a tube echoes: a
// pulse-echo beam sees a tube at its near wall, r from its axis towards the transducer, so a
// line through the echoes of a sheath (R) and its guidewire (ρ) is tilted by (R − ρ)/length.
//
// In: a Volume, a start line near the catheter, the background voxel value and the catheter's
// outer diameters (mm; 0: the echoes are the axis). Out: the axis and the echoes' own line in
// the volume's image frame (mm). Beams (BeamGeometry) run from the probe apex when the volume
// knows its image-to-probe transform (Volume::has_image_to_probe) or the caller gives them;
// when the beams are unknown the fit is the symmetric centre-line fit (no first-echo rule, no
// near-wall offset: the axis through the centre of the bright cross-section).
// Clipped echoes: a voxel at the display's top (255) is only known to be at least that bright;
// one behind another clipped voxel along its beam is the same saturated echo (a metal wire's
// ring-down), not a first echo — so a saturated wire's echo locus is its near wall, ρ from its
// axis, as the model says (docs/detector.md#algorithm, step 4).
// Errors: Validate throws std::invalid_argument naming the field, for a catheter the model
// cannot describe too (a wire not thinner than the sheath, a sheath wider than the fit's
// cylinder); FitEchoAxis returns empty when fewer than 4 echoes lie near the start line.
// Details: docs/detector.md#algorithm (step 4)
#pragma once

#include <limits>
#include <optional>

#include "formats/parameter_spec.h"
#include "imaging/volume.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

// The axis fit's tunable parameters (formats/parameter_spec.h): declared once, read by the
// options' defaults, by Validate and by the pipeline's registry (live/pipeline_parameters.h).
namespace params {
inline constexpr formats::ParameterSpec kFitRadiusMm{
    "detector.fit_radius_mm",
    "mm",
    formats::ParameterKind::kReal,
    0.5,
    10,
    2.5,
    "axis fit: echoes within this distance of the Radon line join the fit (the catheter's "
    "radius plus the point-spread function)"};
inline constexpr formats::ParameterSpec kFirstEchoMm{
    "detector.first_echo_mm",
    "mm",
    formats::ParameterKind::kReal,
    0,
    20,
    3.0,
    "axis fit: look-back along the beam for the first-echo rule (a brighter echo this close "
    "nearer the probe makes a sample a reverberation or the far wall; at least the sheath's "
    "diameter + 1 mm is used); 0: off"};
// ≤ 10 mm: 30 Fr, above the largest cardiac delivery sheaths (24–26 Fr, ~8.7 mm).
inline constexpr formats::ParameterSpec kSheathDiameterMm{
    "detector.sheath_diameter_mm",
    "mm",
    formats::ParameterKind::kReal,
    0,
    10,
    2.5,
    "the sheath's outer diameter: a beam echoes at the near wall, so the axis lies a radius "
    "behind the echoes; 0: the echoes are the axis; <= 10 mm (30 Fr) and <= 2 x "
    "detector.fit_radius_mm (the fit gathers the wall's echoes within that radius)"};
inline constexpr formats::ParameterSpec kWireDiameterMm{
    "detector.wire_diameter_mm",
    "mm",
    formats::ParameterKind::kReal,
    0,
    5,
    0.9,
    "the guidewire's outer diameter (its near-wall offset beyond the sheath), below the "
    "sheath's (it runs in the sheath's lumen), <= 5 mm; 0 with no sheath model"};
}  // namespace params

struct EchoAxisFitOptions {
  // echoes within this distance of the start line
  double fit_radius_mm = params::kFitRadiusMm.default_value;
  // look-back along the beam for the first-echo rule; 0: off
  double first_echo_mm = params::kFirstEchoMm.default_value;
  // outer diameter of the sheath; 0: echoes are the axis; ≤ 2 fit_radius_mm
  double sheath_diameter_mm = params::kSheathDiameterMm.default_value;
  // outer diameter of the guidewire, < sheath_diameter_mm (0 when that is 0)
  double wire_diameter_mm = params::kWireDiameterMm.default_value;
  // The axis comes from the sheath's echoes alone when they span at least this much.
  double min_sheath_span_mm = 10.0;
  // Echo threshold between the background (0) and the catheter's echo level (→ 1).
  double echo_level_fraction = 0.6;

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

struct EchoAxisFit {
  Line3 axis;                 // the catheter's axis (sign of direction arbitrary)
  Line3 echo_line;            // TLS line of the echoes themselves
  bool wire_found = false;    // a sheath/wire breakpoint improved the fit
  double sheath_end_s = 0.0;  // breakpoint, coordinate along `axis` (valid if wire_found)
  double wire_direction = 0;  // +1: the wire lies at s > sheath_end_s along axis.direction
  int echo_count = 0;
  double rms_mm = 0.0;  // weighted RMS distance of the moved echoes to the axis
  // The echoes' extent along `axis` (its parameters, min and max).
  double echo_s_min = 0.0, echo_s_max = 0.0;
};

// Where the beams come from, in the image frame (mm): from a probe apex (a pyramidal or
// sector scan), all along one direction (a linear probe: parallel beams), or unknown (a
// volume reconstructed or compounded from many probe poses, a file without the transform).
struct BeamGeometry {
  enum class Kind { kUnknown, kApex, kParallel };
  Kind kind = Kind::kUnknown;
  Eigen::Vector3d apex_mm = Eigen::Vector3d::Zero();  // kApex
  // kParallel: the beam direction. kApex: the probe's axis (+z of the probe frame) for points
  // not in front of the apex; zero: every point's beam runs from the apex.
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();

  bool known() const { return kind != Kind::kUnknown; }
  // From the volume's image-to-probe transform (imaging/sim/probe.h: the probe frame's origin
  // is the apex, +z its axis); unknown when the volume does not have one.
  static BeamGeometry FromVolume(const imaging::Volume& volume);
  // Throws std::invalid_argument when `apex_mm` is not finite.
  static BeamGeometry FromApex(const Eigen::Vector3d& apex_mm);
  // Throws std::invalid_argument when `direction` is not finite or is (nearly) zero.
  static BeamGeometry Parallel(const Eigen::Vector3d& direction);
  // Unit beam direction (away from the transducer) at p; unknown: zero.
  Eigen::Vector3d At(const Eigen::Vector3d& p_mm) const;
};

// Beam direction (unit, away from the transducer) at image-frame point p, from the volume's
// image-to-probe transform (the identity when it has none: beams from the image origin).
Eigen::Vector3d BeamDirectionAt(const imaging::Volume& volume, const Eigen::Vector3d& p_mm);

// Empty when fewer than 4 echoes lie near `start`. Beams from BeamGeometry::FromVolume.
std::optional<EchoAxisFit> FitEchoAxis(const imaging::Volume& volume, const Line3& start,
                                       double background, const EchoAxisFitOptions& options);
// The same with the beams given; unknown beams: the symmetric centre-line fit. Voxels farther
// than `max_along_mm` along `start` from start.point are left out (the tissue beyond a tip).
std::optional<EchoAxisFit> FitEchoAxis(
    const imaging::Volume& volume, const Line3& start, double background,
    const EchoAxisFitOptions& options, const BeamGeometry& beams,
    double max_along_mm = std::numeric_limits<double>::infinity());

}  // namespace echoservo::tracking
