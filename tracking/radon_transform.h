// The 3D Radon (line-integral) transform of a sparse intensity field, and the search for its
// strongest line over a set of directions: the search stage of the catheter detector.
//
// A volume is reduced to a level: voxels max-pooled by an integer factor, keeping the cells
// brighter than the level's background (median of its non-zero cells), each weighted by
// (value − background)², at their physical positions (mm, image frame). For a direction d
// the cells are projected onto the plane ⟂ d and splatted bilinearly into a 2D histogram
// with bins of the level's cell size: each bin is the line integral of the weights along one
// line parallel to d. A straight bright line parallel to d is a point peak of that
// histogram; a surface seen edge-on is a ridge. A peak is scored by its value minus the
// maximum of the 16-bin ring 2 bins around it, which cancels ridges and ridge ends.
//
// Units: mm in the volume's image frame; directions are unit vectors; angles in rad.
#pragma once

#include <Eigen/Core>
#include <span>
#include <vector>

#include "imaging/volume.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

struct RadonCell {
  Eigen::Vector3d p_mm;  // cell centre, image frame
  double weight;         // (value − background)², > 0
};

// One resolution level of a volume.
struct RadonLevel {
  std::vector<RadonCell> cells;
  double bin_mm = 1.0;                                  // histogram bin (the cell size)
  Eigen::Vector3d centre_mm = Eigen::Vector3d::Zero();  // histogram origin
  double half_extent_mm = 1.0;                          // histogram half-width
  double background = 0.0;                              // median non-zero pooled value
  double max_depth_z_mm = 0.0;  // peaks whose line lies deeper (image z) are ignored
};

// Max-pools `volume` by `factor` (≥ 1) and keeps the cells above the background. Lines whose
// point nearest the volume centre lies deeper than `max_depth_fraction` of the volume's z
// extent are later ignored by RadonPeaks (1: none).
RadonLevel MakeRadonLevel(const imaging::Volume& volume, int factor, double max_depth_fraction);

struct RadonPeak {
  double score = -1.0;      // contrast of the peak against its ring (weight units)
  double a_mm = 0, c_mm = 0;  // offset in the plane ⟂ d, from the level centre
  double z = 0.0;           // robust z-score among the histogram's bins (first peak only)
};

// Restricts peaks to lines within `radius_mm` of `line` (measured in the plane ⟂ d).
struct RadonWindow {
  Line3 line;
  double radius_mm = 0.0;
};

// An orthonormal basis (u, w) of the plane ⟂ d (d unit).
void PlaneBasis(const Eigen::Vector3d& d, Eigen::Vector3d& u, Eigen::Vector3d& w);

// All local-maximum peaks of the histogram for direction d, best first. `want_z` fills the
// first peak's z-score.
std::vector<RadonPeak> RadonPeaks(const RadonLevel& level, const Eigen::Vector3d& d,
                                  const RadonWindow* window, bool want_z);

// The line of `peak` in direction d.
Line3 PeakLine(const RadonLevel& level, const Eigen::Vector3d& d, const RadonPeak& peak);

// n directions on the hemisphere z > 0, Fibonacci-spaced (≈ √(2π/n) rad apart).
std::vector<Eigen::Vector3d> FibonacciHemisphere(int n);
// steps² directions on a square grid of tangent-plane angles within ±half_rad around d.
std::vector<Eigen::Vector3d> DirectionCone(const Eigen::Vector3d& d, double half_rad, int steps);

struct RadonSearchResult {
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  RadonPeak peak;
  std::vector<double> scores;  // each direction's best score (≥ 0), in input order
};

// Best peak over `directions`, in parallel (TBB).
RadonSearchResult SearchDirections(const RadonLevel& level,
                                   std::span<const Eigen::Vector3d> directions,
                                   const RadonWindow* window);

}  // namespace echoservo::tracking
