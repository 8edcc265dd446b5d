#include "tracking/reflector_line.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace echoservo::tracking {
namespace {

// Orthogonal least-squares line through `points` (PLUS's PlaneParametersEstimator::
// LeastSquaresEstimate): the mean, and the normal = the scatter's eigenvector of the smallest
// eigenvalue, signed as PLUS's EISPACK solver returns it (n_y < 0 when the points spread more
// along x than y, else n_x > 0; checked against a port of tred2/tql2 on 20 000 random point
// sets). nullopt when all points coincide.
std::optional<ConsensusLine> RlOrthogonalFit(std::span<const Eigen::Vector2d> points) {
  if (points.size() < 2) return std::nullopt;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector2d& p : points) scatter += (p - mean) * (p - mean).transpose();
  if (!(scatter.trace() > 0.0)) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(scatter);
  Eigen::Vector2d normal = eig.eigenvectors().col(0);  // eigenvalues ascending
  if (scatter(0, 0) > scatter(1, 1) ? normal.y() > 0.0 : normal.x() < 0.0) normal = -normal;
  ConsensusLine line;
  line.point = mean;
  line.direction = Eigen::Vector2d(-normal.y(), normal.x());
  line.inliers = static_cast<int>(points.size());
  double ss = 0.0;
  for (const Eigen::Vector2d& p : points) ss += std::pow(normal.dot(p - mean), 2);
  line.rms_px = std::sqrt(ss / static_cast<double>(points.size()));
  return line;
}

}  // namespace

PixelRegion FitClipToFrame(const ClipRectangle& clip, int width, int height) {
  if (clip.width <= 0 || clip.height <= 0) return {0, 0, width, height};
  if (clip.x < 0 || clip.y < 0 || clip.x >= width || clip.y >= height) {
    throw std::invalid_argument("clip rectangle origin (" + std::to_string(clip.x) + ", " +
                                std::to_string(clip.y) + ") lies outside the " +
                                std::to_string(width) + " x " + std::to_string(height) +
                                " pixel frame");
  }
  // PLUS cuts a rectangle reaching past the frame at the frame's edge.
  return {clip.x, clip.y, std::min(clip.width, width - clip.x),
          std::min(clip.height, height - clip.y)};
}

std::optional<ScanlinePeak> LargestPeak(std::span<const int> profile, double fraction) {
  if (profile.empty()) return std::nullopt;
  const double threshold = fraction * *std::max_element(profile.begin(), profile.end());
  ScanlinePeak best, current;
  bool under = false;
  for (std::size_t i = 0; i < profile.size(); ++i) {
    const int v = profile[i];
    if (v > threshold && !under) {
      under = true;
      current = {static_cast<int>(i), static_cast<int>(i) + 1, v, v};
    } else if (v > threshold && under) {
      current.area += v;
      current.end = static_cast<int>(i) + 1;
      current.max = std::max(current.max, v);
    } else if (v < threshold && under) {
      under = false;
      if (current.area > best.area) best = current;
    }
    // v == threshold: PLUS neither opens nor closes a run (nor adds to its area).
  }
  if (best.area == 0) return std::nullopt;
  return best;
}

std::optional<double> PeakCentreOfGravity(std::span<const int> profile, int start,
                                          double fraction) {
  if (profile.empty() || start < 0 || static_cast<std::size_t>(start) >= profile.size())
    return std::nullopt;
  const double threshold = fraction * *std::max_element(profile.begin(), profile.end());
  double weighted = 0.0;
  long long sum = 0;
  std::size_t i = static_cast<std::size_t>(start);
  for (; i < profile.size() && profile[i] > threshold; ++i) {
    weighted += static_cast<double>(i) * profile[i];
    sum += profile[i];
  }
  if (sum == 0 || i == profile.size()) return std::nullopt;
  return weighted / static_cast<double>(sum);
}

std::vector<int> ScanlineColumns(const PixelRegion& region, int count) {
  std::vector<int> columns;
  if (count < 2 || region.width < 1) return columns;
  const double spacing = static_cast<double>(region.width - 1) / (count - 1);
  for (int i = 0; i < count; ++i)
    columns.push_back(region.x + static_cast<int>(std::trunc(spacing * i)));
  return columns;
}

std::optional<ConsensusLine> FitConsensusLine(std::span<const Eigen::Vector2d> points,
                                              double inlier_px) {
  const std::size_t n = points.size();
  if (n < 2) return std::nullopt;
  const double tol2 = inlier_px * inlier_px;
  std::vector<char> votes(n), best_votes;
  std::size_t best_count = 0;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      const Eigen::Vector2d d = points[j] - points[i];
      const double len = d.norm();
      if (!(len > 0.0)) continue;  // PLUS: a singular pair gives no hypothesis
      const Eigen::Vector2d normal(-d.y() / len, d.x() / len);
      std::size_t count = 0;
      for (std::size_t k = 0; k < n; ++k) {
        const double s = normal.dot(points[k] - points[i]);
        votes[k] = s * s < tol2;
        count += votes[k] ? 1 : 0;
      }
      if (count > best_count) {
        best_count = count;
        best_votes = votes;
      }
    }
  }
  if (best_count == 0) return std::nullopt;
  std::vector<Eigen::Vector2d> inliers;
  for (std::size_t k = 0; k < n; ++k)
    if (best_votes[k]) inliers.push_back(points[k]);
  return RlOrthogonalFit(inliers);
}

std::optional<ReflectorLine> FindReflectorLine(std::span<const std::uint8_t> pixels, int width,
                                               int height, const ReflectorLineOptions& o) {
  if (width < 1 || height < 1 ||
      pixels.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    throw std::invalid_argument("FindReflectorLine: frame of " + std::to_string(pixels.size()) +
                                " pixels is not " + std::to_string(width) + " x " +
                                std::to_string(height));
  }
  if (o.scanlines < 2 || !(o.peak_fraction > 0.0 && o.peak_fraction <= 1.0) ||
      !(o.inlier_px > 0.0) || !(o.min_direction_x >= 0.0 && o.min_direction_x < 1.0)) {
    throw std::invalid_argument(
        "FindReflectorLine: options out of range (scanlines >= 2, peak_fraction in (0, 1], "
        "inlier_px > 0, min_direction_x in [0, 1))");
  }
  const PixelRegion region = FitClipToFrame(o.clip, width, height);
  std::vector<Eigen::Vector2d> peaks;
  std::vector<int> profile(static_cast<std::size_t>(region.height));
  for (const int x : ScanlineColumns(region, o.scanlines)) {
    for (int r = 0; r < region.height; ++r)
      profile[static_cast<std::size_t>(r)] =
          pixels[static_cast<std::size_t>(region.y + r) * static_cast<std::size_t>(width) +
                 static_cast<std::size_t>(x)];
    const std::optional<ScanlinePeak> peak = LargestPeak(profile, o.peak_fraction);
    if (!peak) continue;
    const std::optional<double> cog = PeakCentreOfGravity(profile, peak->start, o.peak_fraction);
    if (!cog) continue;
    peaks.emplace_back(static_cast<double>(x), region.y + *cog);
  }
  // PLUS only logs when fewer than 5 scanlines have a peak; the fit needs 2.
  const std::optional<ConsensusLine> line = FitConsensusLine(peaks, o.inlier_px);
  if (!line || line->direction.x() < o.min_direction_x) return std::nullopt;
  const double t = (region.x + 0.5 * region.width - line->point.x()) / line->direction.x();
  ReflectorLine out;
  out.depth_px = std::abs(line->point.y() + t * line->direction.y());
  out.slope = line->direction.y() / line->direction.x();
  out.scanlines = static_cast<int>(peaks.size());
  out.inliers = line->inliers;
  out.rms_px = line->rms_px;
  return out;
}

}  // namespace echoservo::tracking
