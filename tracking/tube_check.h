// Is a detected bright line a tube (a catheter) or part of a surface (a wall, the edge of a
// plate, a tissue ridge)? Both give a peak in a Radon transform; only a tube is dark all
// around it.
//
// Tubularity in [0, 1]: over cross-sections every step_mm, 1 − amplitude(brightest sector
// around the core)/amplitude(core), skipping the sector of the reverberation ribbon; the median
// over the run. ≈ 1 for a catheter in blood or water, ≈ 0 for a line in a surface.
// The ribbon: a catheter's reverberation copies are displaced along the beam, so in a
// cross-section they extend in ONE direction from the core, the beam's projection ⟂ the axis.
// With the beams known (BeamGeometry) that sector is skipped. With the beams unknown the
// cross-sections decide: in one, the brightest direction around the core is a ribbon when its
// brightness decays away from the core (far/near amplitude below ribbon_decay_ratio); when at
// least half the cross-sections show one and agree on its direction (RibbonDirection), that
// sector is skipped. A surface through or ending at the line is uniform along it: not skipped.
// Units: mm and rad in the volume's image frame; values are voxel (display) values.
// Errors: Validate throws std::invalid_argument naming the field.
// Details: docs/detector.md#algorithm (step 7)
#pragma once

#include <Eigen/Core>
#include <optional>

#include "imaging/volume.h"
#include "tracking/echo_axis_fit.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

struct TubeCheckOptions {
  double core_radius_mm = 1.5;
  double ring_inner_mm = 3.0;
  double ring_outer_mm = 5.0;
  int sectors = 12;
  double behind_half_angle_rad = 0.6;
  double step_mm = 1.0;
  // Unknown beams: the brightest direction is a reverberation ribbon when the median amplitude
  // along it at ribbon_far_mm (6–9 mm) is below this fraction of that at the ring (2–4.5 mm).
  double ribbon_decay_ratio = 0.6;

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

// Tubularity in [0, 1] of `axis` between parameters s_from and s_to (s_from ≤ s_to); 0 when
// no cross-section lies inside the volume.
// The reverberation ribbon's direction ⟂ the axis (unit: the beam's projection, away from
// the transducer), judged from the cross-sections every step_mm between s_from and s_to: when
// at least half show a ribbon (the unknown-beam rule above) and they agree; else nullopt.
std::optional<Eigen::Vector3d> RibbonDirection(const imaging::Volume& volume, const Line3& axis,
                                               double s_from, double s_to, double dynamic_range_db,
                                               const TubeCheckOptions& options);

// Beams from BeamGeometry::FromVolume.
double Tubularity(const imaging::Volume& volume, const Line3& axis, double s_from, double s_to,
                  double dynamic_range_db, const TubeCheckOptions& options);
// With `beams` unknown, the ribbon is looked for (RibbonDirection) unless `search_ribbon` is
// false (the caller looked over the same axis and range and found none).
double Tubularity(const imaging::Volume& volume, const Line3& axis, double s_from, double s_to,
                  double dynamic_range_db, const TubeCheckOptions& options,
                  const BeamGeometry& beams, bool search_ribbon = true);

}  // namespace echoservo::tracking
