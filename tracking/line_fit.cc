#include "tracking/line_fit.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace echoservo::tracking {
namespace {

void Require(bool ok, const std::string& where, const std::string& field, const std::string& why) {
  if (!ok) throw std::invalid_argument(where + ": field '" + field + "' " + why);
}

// median(d) / √(2 ln 2) is the Rayleigh σ: the per-axis noise of points scattered
// isotropically (Gaussian) around the line.
const double kRayleighMedianPerSigma = std::sqrt(2.0 * std::log(2.0));

// The messages are built only on failure: these checks run on every point of every fit.
void RequireFinitePoints(std::span<const Eigen::Vector3d> points, const std::string& where) {
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!points[i].allFinite())
      Require(false, where, "points[" + std::to_string(i) + "]", "must be finite");
}

// Weighted TLS fit without input checks. Empty optional when fewer than 2 distinct points
// carry positive weight (weights empty = all 1).
std::optional<Line3> WeightedFit(std::span<const Eigen::Vector3d> points,
                                 std::span<const double> weights) {
  const auto weight = [&](std::size_t i) { return weights.empty() ? 1.0 : weights[i]; };
  const Eigen::Vector3d* first = nullptr;
  bool distinct = false;
  double total = 0.0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!(weight(i) > 0.0)) continue;
    if (first == nullptr) first = &points[i];
    distinct = distinct || points[i] != *first;
    total += weight(i);
    sum += weight(i) * points[i];
  }
  if (!distinct) return std::nullopt;
  const Eigen::Vector3d centroid = sum / total;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!(weight(i) > 0.0)) continue;
    const Eigen::Vector3d r = points[i] - centroid;
    scatter.noalias() += weight(i) * r * r.transpose();
  }
  // Eigenvalues come sorted increasing: the last eigenvector spans the largest spread.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  assert(solver.info() == Eigen::Success);
  Eigen::Vector3d direction = solver.eigenvectors().col(2).normalized();
  Eigen::Index largest = 0;
  direction.cwiseAbs().maxCoeff(&largest);
  if (direction[largest] < 0.0) direction = -direction;
  return Line3{centroid, direction};
}

// RMS distance of the points to their centroid: the length scale for tolerances.
double RmsSpread(std::span<const Eigen::Vector3d> points) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) centroid += p;
  centroid /= static_cast<double>(points.size());
  double sum_sq = 0.0;
  for (const Eigen::Vector3d& p : points) sum_sq += (p - centroid).squaredNorm();
  return std::sqrt(sum_sq / static_cast<double>(points.size()));
}

double Median(std::vector<double> values) {
  assert(!values.empty());
  const std::size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid), values.end());
  const double upper = values[mid];
  if (values.size() % 2 == 1) return upper;
  const double lower =
      *std::max_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid));
  return 0.5 * (lower + upper);
}

double RobustWeight(RobustLoss loss, double c, double u) {
  switch (loss) {
    case RobustLoss::kHuber:
      return u <= c ? 1.0 : c / u;
    case RobustLoss::kTukey: {
      if (u >= c) return 0.0;
      const double t = 1.0 - (u / c) * (u / c);
      return t * t;
    }
  }
  return 0.0;
}

}  // namespace

Line3 Line3::Through(const Eigen::Vector3d& point, const Eigen::Vector3d& direction) {
  Require(point.allFinite(), "Line3", "point", "must be finite");
  Require(direction.allFinite(), "Line3", "direction", "must be finite");
  const double norm = direction.norm();
  Require(norm > 0.0 && std::isfinite(norm), "Line3", "direction", "must be a nonzero vector");
  return Line3{point, direction / norm};
}

double PointToLineDistance(const Line3& line, const Eigen::Vector3d& p) {
  const double norm = line.direction.norm();
  assert(norm > 0.0 && "Line3::direction must be nonzero");
  return (p - line.point).cross(line.direction).norm() / norm;
}

double AngleBetweenLines(const Line3& a, const Line3& b) {
  assert(a.direction.norm() > 0.0 && b.direction.norm() > 0.0);
  return std::atan2(a.direction.cross(b.direction).norm(), std::abs(a.direction.dot(b.direction)));
}

Line3 FitLine(std::span<const Eigen::Vector3d> points, std::span<const double> weights) {
  const std::string where = "FitLine";
  RequireFinitePoints(points, where);
  if (!weights.empty()) {
    Require(weights.size() == points.size(), where, "weights",
            "must be empty or have one entry per point (" + std::to_string(weights.size()) +
                " weights for " + std::to_string(points.size()) + " points)");
    for (std::size_t i = 0; i < weights.size(); ++i)
      if (!(std::isfinite(weights[i]) && weights[i] >= 0.0))
        Require(false, where, "weights[" + std::to_string(i) + "]", "must be finite and >= 0");
  }
  const std::optional<Line3> line = WeightedFit(points, weights);
  Require(line.has_value(), where, "points",
          "must hold at least 2 distinct points (with positive weight) to define a line");
  return *line;
}

RobustLineFit FitLineRobust(std::span<const Eigen::Vector3d> points,
                            const RobustLineFitOptions& options) {
  const std::string where = "FitLineRobust";
  Require(std::isfinite(options.tuning_constant) && options.tuning_constant > 0.0, where,
          "tuning_constant", "must be finite and > 0 (in units of the residual scale)");
  Require(options.max_iterations >= 1, where, "max_iterations", "must be >= 1");
  Require(std::isfinite(options.tolerance) && options.tolerance >= 0.0, where, "tolerance",
          "must be finite and >= 0");
  if (options.initial_line) {
    Require(options.initial_line->point.allFinite(), where, "initial_line.point", "must be finite");
    Require(
        options.initial_line->direction.allFinite() && options.initial_line->direction.norm() > 0.0,
        where, "initial_line.direction", "must be finite and nonzero");
  }
  RequireFinitePoints(points, where);
  std::optional<Line3> start = WeightedFit(points, {});
  Require(start.has_value(), where, "points",
          "must hold at least 2 distinct points to define a line");
  if (options.initial_line)
    start = Line3::Through(options.initial_line->point, options.initial_line->direction);

  const double spread = RmsSpread(points);
  const double min_scale = 1e-12 * spread;
  RobustLineFit fit;
  fit.line = *start;
  fit.weights.assign(points.size(), 1.0);
  std::vector<double> distances(points.size());
  const auto update_weights = [&] {
    for (std::size_t i = 0; i < points.size(); ++i)
      distances[i] = PointToLineDistance(fit.line, points[i]);
    fit.scale = std::max(Median(distances) / kRayleighMedianPerSigma, min_scale);
    for (std::size_t i = 0; i < points.size(); ++i) {
      fit.weights[i] =
          RobustWeight(options.loss, options.tuning_constant, distances[i] / fit.scale);
    }
  };

  update_weights();
  for (fit.iterations = 1; fit.iterations <= options.max_iterations; ++fit.iterations) {
    const std::optional<Line3> next = WeightedFit(points, fit.weights);
    // At least half the points lie within the median distance, i.e. within
    // √(2 ln 2) · σ̂ ≈ 1.18 σ̂, so a usual tuning constant leaves them positive weight; only an
    // odd cloud (those points all identical) leaves nothing to fit: keep the last line.
    if (!next) {
      --fit.iterations;
      break;
    }
    const double turn = AngleBetweenLines(fit.line, *next);
    const double shift = PointToLineDistance(fit.line, next->point);
    fit.line = *next;
    update_weights();
    if (turn <= options.tolerance && shift <= options.tolerance * spread) {
      fit.converged = true;
      break;
    }
  }
  fit.iterations = std::min(fit.iterations, options.max_iterations);
  return fit;
}

}  // namespace echoservo::tracking
