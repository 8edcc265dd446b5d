// Placing the simulated scanner's catheter and annulus by a few clinical-looking numbers, the
// one convention shared by the detector's tests, benchmark and accuracy harness.
//
// The catheter's axis is yawed about the probe axis (world +z) and tilted towards depth; its
// guidewire tip (at advance 0) lies at (lateral, 0, depth) in the world (tank) frame, and the
// annulus is centred on the axis 15 mm beyond that tip, facing the catheter. Units: mm, deg.
#pragma once

#include "imaging/sim/simulated_scanner.h"

namespace echoservo::imaging::sim {

struct CatheterScenePose {
  double yaw_deg = 0.0;     // about the probe axis; 0: entering from −x
  double tilt_deg = 10.0;   // towards depth
  double depth_mm = 60.0;   // tip depth (world z)
  double lateral_mm = 0.0;  // tip x
  double advance_mm = 0.0;  // catheter advance along its axis
};

// Sets options.catheter_pose and options.annulus_to_world (uses options.catheter_geometry).
void PlaceCatheterScene(const CatheterScenePose& pose, SimulatedScannerOptions& options);

}  // namespace echoservo::imaging::sim
