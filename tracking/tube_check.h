// Is a detected bright line a tube (a catheter) or part of a surface (a wall, the edge of a
// plate, a tissue ridge)? Both give a peak in a Radon transform; only a tube is dark all
// around it.
//
// At cross-sections every `step_mm` along the bright run, the core value is the maximum
// within `core_radius_mm` of the axis and each of `sectors` angular sectors ⟂ the axis is
// summarised by its mean value at radii [ring_inner_mm, ring_outer_mm]. The sector behind the
// line along the beam (within `behind_half_angle_rad` of the beam direction ⟂ the axis) is
// skipped: reverberation comet tails and shadows lie there. A cross-section's tubularity is
// 1 − (echo amplitude of the brightest remaining sector) / (amplitude of the core), values
// turned into amplitudes over the display's dynamic range; the line's is the median over
// its cross-sections: ≈ 1 for a catheter in blood or water (blood and tissue speckle lie
// 20–40 dB below a catheter's echo), ≈ 0 for a line lying in a surface.
//
// Units: mm and rad in the volume's image frame; values are voxel (display) values.
#pragma once

#include "imaging/volume.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

struct TubeCheckOptions {
  double core_radius_mm = 1.5;
  double ring_inner_mm = 3.0;
  double ring_outer_mm = 5.0;
  int sectors = 12;
  double behind_half_angle_rad = 0.6;
  double step_mm = 1.0;

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

// Tubularity in [0, 1] of `axis` between parameters s_from and s_to (s_from ≤ s_to); 0 when
// no cross-section lies inside the volume.
double Tubularity(const imaging::Volume& volume, const Line3& axis, double s_from, double s_to,
                  double dynamic_range_db, const TubeCheckOptions& options);

}  // namespace echoservo::tracking
