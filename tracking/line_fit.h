// Straight 3D lines and their least-squares fit to points: the model of a catheter shaft
// segment seen in a volume.
//
// A Line3 is a point and a unit direction, in the frame and length unit of the points it was
// built from (mm in the image or reference frame in this project); the direction's sign
// carries no meaning (angles between lines ignore it). FitLine: total (orthogonal) least
// squares. FitLineRobust: a Huber or Tukey M-estimator by iteratively reweighted least squares.
// Errors: std::invalid_argument, in the cases listed on each function.
// Details: docs/detector.md#straight-line-fits-trackingline_fith
#pragma once

#include <Eigen/Core>
#include <optional>
#include <span>
#include <vector>

namespace echoservo::tracking {

struct Line3 {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // unit length

  // Normalises `direction`; throws std::invalid_argument naming the field when `point` or
  // `direction` is not finite, or `direction` is zero.
  static Line3 Through(const Eigen::Vector3d& point, const Eigen::Vector3d& direction);

  // Signed coordinate of the orthogonal projection of p along `direction`, from `point`.
  double Parameter(const Eigen::Vector3d& p) const { return (p - point).dot(direction); }
  // The point of the line closest to p.
  Eigen::Vector3d Project(const Eigen::Vector3d& p) const {
    return point + Parameter(p) * direction;
  }
};

// Perpendicular distance from p to the line (unit of the points).
double PointToLineDistance(const Line3& line, const Eigen::Vector3d& p);

// Angle between the two lines' directions in rad, in [0, π/2]: the sign of the directions
// is ignored. Computed as atan2(|a × b|, |a · b|), accurate for small angles.
double AngleBetweenLines(const Line3& a, const Line3& b);

// Total-least-squares line through `points`, optionally weighted (weights.size() must then
// equal points.size(); each weight finite and ≥ 0). The returned point is the weighted
// centroid; the direction's sign is chosen so that its largest-magnitude component is > 0.
// Throws std::invalid_argument for a non-finite point or weight, a size mismatch, or fewer
// than 2 distinct points among those with positive weight.
Line3 FitLine(std::span<const Eigen::Vector3d> points, std::span<const double> weights = {});

enum class RobustLoss {
  // w(u) = min(1, c / u): every outlier keeps a bounded pull, so clustered clutter biases
  // the line (by degrees when the cluster sits off the segment's centre).
  kHuber,
  // w(u) = (1 − (u / c)²)² for u < c, else 0: outliers beyond c σ̂ get no weight at all.
  kTukey,
};

struct RobustLineFitOptions {
  RobustLoss loss = RobustLoss::kTukey;
  // c, in units of σ̂. 4.685 (Tukey) and 1.345 (Huber) are the usual 95 %-efficiency values.
  double tuning_constant = 4.685;
  int max_iterations = 100;
  // Stops when a pass turns the direction by less than `tolerance` rad and moves the line by
  // less than `tolerance` times the RMS spread of the points.
  double tolerance = 1e-10;
  // Starting line; the plain FitLine of all points when absent. A good start (the previous
  // volume's line) helps when outliers are many and clustered.
  std::optional<Line3> initial_line;

  static RobustLineFitOptions Tukey(double c = 4.685) {
    RobustLineFitOptions options;
    options.loss = RobustLoss::kTukey;
    options.tuning_constant = c;
    return options;
  }
  static RobustLineFitOptions Huber(double k = 1.345) {
    RobustLineFitOptions options;
    options.loss = RobustLoss::kHuber;
    options.tuning_constant = k;
    return options;
  }
};

struct RobustLineFit {
  Line3 line;
  std::vector<double> weights;  // final IRLS weight of each point, in [0, 1]
  // σ̂ = median(d_i) / √(2 ln 2): the median residual distance turned into the per-axis
  // standard deviation of isotropic Gaussian noise (d_i is then Rayleigh distributed).
  // Floored at 1e-12 × the RMS spread of the points so exact data does not divide by 0.
  double scale = 0.0;
  int iterations = 0;
  bool converged = false;
};

// IRLS fit robust to outliers (see above). Same input checks as FitLine (unweighted), plus
// std::invalid_argument naming the options field when tuning_constant is not finite and
// > 0, max_iterations < 1, tolerance is not finite and ≥ 0, or initial_line is not finite.
RobustLineFit FitLineRobust(std::span<const Eigen::Vector3d> points,
                            const RobustLineFitOptions& options = {});

}  // namespace echoservo::tracking
