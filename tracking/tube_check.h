// Is a detected bright line a tube (a catheter) or part of a surface (a wall, the edge of a
// plate, a tissue ridge)? Both give a peak in a Radon transform; only a tube is dark all
// around it.
//
// Tubularity in [0, 1]: over cross-sections every step_mm, 1 − amplitude(brightest sector
// around the core)/amplitude(core), skipping the sector behind the line along the beam; the
// median over the run. ≈ 1 for a catheter in blood or water, ≈ 0 for a line in a surface.
// Units: mm and rad in the volume's image frame; values are voxel (display) values.
// Errors: Validate throws std::invalid_argument naming the field.
// Details: docs/detector.md#algorithm (step 7)
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
