// Full-resolution fit of the catheter axis to its echoes, modelling where a tube echoes.
//
// A pulse-echo beam sees a tube (sheath, guidewire) at its near wall: the first echo of a
// tube of radius r lies r from its axis, towards the transducer, on the normal
// n = b⊥ / |b⊥| (b the beam direction at the echo, b⊥ its part ⟂ the axis). A catheter is
// a sheath of radius R with a thinner guidewire of radius ρ protruding from it, so the echo
// locus is the axis offset by R along the shaft and by ρ beyond the sheath end: a line
// through all echoes is tilted by (R − ρ) / (visible length) — degrees for a 2.5 mm sheath.
//
// The fit: (1) the first echoes near the search line (voxels with no brighter voxel up to
// `first_echo_mm` nearer the transducer along the beam: comet tails and the far wall lie
// behind) above a threshold `echo_level_fraction` of the way from the background to the
// catheter's echo level (the 99th percentile of the voxels near the line: speckle fills the
// rest) are gathered, weighted by (value − threshold)², and a TLS line is fitted to them in
// shrinking cylinders; (2) each echo is moved onto the axis by r(s) along its n, with
// r(s) = R on the sheath side and ρ on the wire side of a breakpoint s_b, and the axis is
// the TLS line of the moved points; s_b and the side the wire is on are chosen by the least
// weighted residual (both sides, s_b every 0.25 mm). The final axis is the TLS line of the
// moved sheath echoes alone when they span ≥ `min_sheath_span_mm`: a metal guidewire's echo
// is spread behind its near wall by reverberation inside the wire (0.3–0.5 mm deeper than
// the wall in simulated volumes), while the sheath's specular near-wall echo is not. With
// R = ρ = 0 the echo line itself is returned.
//
// Beams: the probe frame's origin is the apex of the pyramidal scan and +z its axis
// (imaging/sim/probe.h); a point's beam runs from the apex (Volume::image_to_probe gives the
// apex in the image frame); a point not in front of the apex uses the probe's +z.
//
// Units: mm in the volume's image frame.
#pragma once

#include <optional>

#include "imaging/volume.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

struct EchoAxisFitOptions {
  double fit_radius_mm = 2.5;       // echoes within this distance of the start line
  double first_echo_mm = 3.0;       // look-back along the beam for the first-echo rule; 0: off
  double sheath_diameter_mm = 2.5;  // outer diameter of the sheath; 0: echoes are the axis
  double wire_diameter_mm = 0.9;    // outer diameter of the guidewire, ≤ sheath_diameter_mm
  // The axis comes from the sheath's echoes alone when they span at least this much.
  double min_sheath_span_mm = 10.0;
  // Echo threshold between the background (0) and the catheter's echo level (→ 1).
  double echo_level_fraction = 0.6;

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

struct EchoAxisFit {
  Line3 axis;                  // the catheter's axis (sign of direction arbitrary)
  Line3 echo_line;             // TLS line of the echoes themselves
  bool wire_found = false;     // a sheath/wire breakpoint improved the fit
  double sheath_end_s = 0.0;   // breakpoint, coordinate along `axis` (valid if wire_found)
  double wire_direction = 0;   // +1: the wire lies at s > sheath_end_s along axis.direction
  int echo_count = 0;
  double rms_mm = 0.0;         // weighted RMS distance of the moved echoes to the axis
};

// Beam direction (unit, away from the transducer) at image-frame point p.
Eigen::Vector3d BeamDirectionAt(const imaging::Volume& volume, const Eigen::Vector3d& p_mm);

// Empty when fewer than 4 echoes lie near `start`.
std::optional<EchoAxisFit> FitEchoAxis(const imaging::Volume& volume, const Line3& start,
                                       double background, const EchoAxisFitOptions& options);

}  // namespace echoservo::tracking
