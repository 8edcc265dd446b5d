// The 3D Radon (line-integral) transform of a sparse intensity field, and the search for its
// strongest line over a set of directions: the search stage of the catheter detector.
//
// A RadonLevel is a volume max-pooled by an integer factor, its cells above the background
// (the median non-zero cell) weighted by (value − background)². For a direction d the cells
// are splatted into a 2D histogram ⟂ d with bins of the cell size: a line parallel to d is a
// point peak, a surface seen edge-on a ridge; a peak scores its value minus its ring's maximum.
// Units: mm in the volume's image frame; directions are unit vectors; angles in rad.
// Details: docs/detector.md#algorithm (steps 1 to 3)
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "imaging/volume.h"
#include "tracking/line_fit.h"

namespace echoservo::tracking {

struct RadonCell {
  Eigen::Vector3d p_mm;  // cell centre, image frame
  double weight;         // (value − background)², > 0
};

// Restricts peaks to lines within `radius_mm` of `line` (measured in the plane ⟂ d).
struct RadonWindow {
  Line3 line;
  double radius_mm = 0.0;
};

// One resolution level of a volume.
struct RadonLevel {
  std::vector<RadonCell> cells;
  double bin_mm = 1.0;                                  // histogram bin (the cell size)
  Eigen::Vector3d centre_mm = Eigen::Vector3d::Zero();  // histogram origin
  double half_extent_mm = 1.0;                          // histogram half-width
  double background = 0.0;                              // median non-zero pooled value
  double min_value = 0.0;       // the cells kept are brighter than this (≥ background)
  double max_depth_z_mm = 0.0;  // peaks whose line lies deeper (image z) are ignored
};

// Max-pools `volume` by `factor` (≥ 1) and keeps the cells above the background. Lines whose
// point nearest the volume centre lies deeper than `max_depth_fraction` of the volume's z
// extent are later ignored by RadonPeaks (1: none).
RadonLevel MakeRadonLevel(const imaging::Volume& volume, int factor, double max_depth_fraction);

// A volume max-pooled by an integer factor: cell (i, j, k) holds the maximum of the voxels
// [f·i, f·i + f) × [f·j, f·j + f) × [f·k, f·k + f) (clipped at the far faces), stored x
// fastest like Volume::voxels().
struct PooledGrid {
  int factor = 1;
  Eigen::Vector3i dims = Eigen::Vector3i::Zero();
  std::vector<std::uint8_t> values;
  std::array<std::int64_t, 256> histogram{};  // of `values`
};

// Max-pools `volume` by `factor` (≥ 1), in parallel (TBB) over output slices.
PooledGrid MaxPool(const imaging::Volume& volume, int factor);
// Pools only the cells whose centres may lie within roi.radius_mm of roi.line (a superset of
// those MakeRadonLevel keeps with the same `roi`); the others, and `histogram`, stay 0. The
// tracking search reads a small part of the volume this way.
PooledGrid MaxPool(const imaging::Volume& volume, int factor, const RadonWindow& roi);
// A region's grids at two nested factors: `coarse` holds the cells of `volume` pooled by
// f · factor that may lie within `roi` (as MaxPool(volume, f · factor, roi)), `fine` the cells
// pooled by f beneath them — among them every cell within roi.radius_mm of its line, so
// MakeRadonLevel(volume, fine, …, &roi, …) keeps the cells it keeps from MaxPool(volume, f,
// roi). The volume is read once (the coarse cells pooled from the fine ones); the other
// cells, and both histograms, stay 0.
struct NestedGrids {
  PooledGrid fine, coarse;
};
NestedGrids MaxPoolNested(const imaging::Volume& volume, int f, int factor, const RadonWindow& roi);
// Pools a pooled grid again by `factor` (≥ 1): the maximum of maxima, i.e. exactly the
// volume pooled by grid.factor · factor (the blocks nest, also at the clipped far faces),
// without reading the volume again.
PooledGrid MaxPool(const PooledGrid& grid, int factor);

// A level's background (the median of the grid's non-zero values) and the value its cells
// must exceed.
struct LevelThresholds {
  double background = 0.0;
  double min_value = 0.0;
};

// The thresholds of a whole pooled grid: `min_contrast` of the way from its background to its
// bright end (the 99th percentile of its non-zero values) above the background.
LevelThresholds GridThresholds(const PooledGrid& grid, double min_contrast);

// The level of a pooled grid of `volume`: with the defaults, the same as
// MakeRadonLevel(volume, grid.factor, max_depth_fraction). With `roi`, only cells whose
// centre lies within roi->radius_mm of roi->line are kept — the tracking search's region —
// while the background stays that of the whole grid, so the kept cells' weights do not
// depend on the region. `min_contrast` > 0 keeps only the cells brighter than the
// background by that fraction of the range up to the grid's bright end (GridThresholds):
// speckle just above the median is most of a tissue volume's cells but, weighted by
// (value − background)², a cell below 1/8 of the range weighs under 1/64 of a bright one.
RadonLevel MakeRadonLevel(const imaging::Volume& volume, const PooledGrid& grid,
                          double max_depth_fraction, const RadonWindow* roi = nullptr,
                          double min_contrast = 0.0);
// The same with given thresholds (e.g. those of an earlier frame, for a grid pooled only in
// a region of interest).
RadonLevel MakeRadonLevel(const imaging::Volume& volume, const PooledGrid& grid,
                          double max_depth_fraction, const RadonWindow* roi,
                          const LevelThresholds& thresholds);

// Median of the non-zero voxels of `volume` (0 when all are zero): the volume's background
// level. Parallel (TBB); runs of zero voxels are skipped 8 at a time.
double MedianNonZeroVoxel(const imaging::Volume& volume);

struct RadonPeak {
  double score = -1.0;        // contrast of the peak against its ring (weight units)
  double a_mm = 0, c_mm = 0;  // offset in the plane ⟂ d, from the level centre
  double z = 0.0;             // robust z-score among the histogram's bins (first peak only)
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

// Median and median absolute deviation (unscaled) of `values`, which are reordered; zeros
// when empty. The robust z-scores of line scores use it.
struct MedianMad {
  double median = 0.0, mad = 0.0;
};
MedianMad ComputeMedianMad(std::vector<double>& values);

struct RadonSearchResult {
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  RadonPeak peak;
  std::vector<double> scores;  // each direction's best score (≥ 0), in input order
  // The directions `scores` belong to and their best peaks (for the coarse-to-fine search:
  // its first stage's), so a caller can revisit the runners-up.
  std::vector<Eigen::Vector3d> directions;
  std::vector<RadonPeak> peaks;
};

// Best peak over `directions`, in parallel (TBB).
RadonSearchResult SearchDirections(const RadonLevel& level,
                                   std::span<const Eigen::Vector3d> directions,
                                   const RadonWindow* window);

struct CoarseToFineOptions {
  int stride = 2;               // the first stage evaluates every stride-th direction
  int top_k = 16;               // the second stage searches near this many of its best
  double neighbour_rad = 0.12;  // ... within this angle (rad)
};

// Best peak over `directions` (an ordered quasi-uniform set, such as FibonacciHemisphere's)
// in two stages: every stride-th direction, then the others within neighbour_rad of the
// top_k best of those. A line's score falls off smoothly with the angle between its
// direction and d, so the set's best direction lies near the first stage's best ones and
// the result is the set's best at about 1/stride of the cost. `scores` holds the first
// stage's scores only (a uniform subsample of the set, for the statistics of line scores).
RadonSearchResult SearchDirectionsCoarseToFine(const RadonLevel& level,
                                               std::span<const Eigen::Vector3d> directions,
                                               const CoarseToFineOptions& options = {},
                                               const RadonWindow* window = nullptr);

// Best peak over DirectionCone(d, half_rad, steps) in two stages: the sub-grid of every other
// row and column (the last ones included), then the grid's other directions next to (within
// one row and column of) the top_k best of those. The score is smooth in the direction near a
// line, so this is the grid's best at about half the cost (steps 9: 25 + ~16 of 81).
// `scores` and `directions` hold the first stage's.
RadonSearchResult SearchConeCoarseToFine(const RadonLevel& level, const Eigen::Vector3d& d,
                                         double half_rad, int steps, int top_k,
                                         const RadonWindow* window);

}  // namespace echoservo::tracking
