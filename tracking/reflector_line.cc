#include "tracking/reflector_line.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace echoservo::tracking {
namespace {

struct RlPeak {
  double x = 0.0;
  double y = 0.0;
};

// Least-squares y = a + b·x over `points` (at least 2 distinct x).
bool RlFitDepthLine(const std::vector<RlPeak>& points, double* a, double* b) {
  const double n = static_cast<double>(points.size());
  if (points.size() < 2) return false;
  double sx = 0, sy = 0;
  for (const RlPeak& p : points) {
    sx += p.x;
    sy += p.y;
  }
  const double mx = sx / n, my = sy / n;
  double sxx = 0, sxy = 0;
  for (const RlPeak& p : points) {
    sxx += (p.x - mx) * (p.x - mx);
    sxy += (p.x - mx) * (p.y - my);
  }
  if (!(sxx > 0.0)) return false;
  *b = sxy / sxx;
  *a = my - *b * mx;
  return true;
}

std::vector<RlPeak> RlInliers(const std::vector<RlPeak>& peaks, double a, double b, double tol) {
  std::vector<RlPeak> in;
  for (const RlPeak& p : peaks)
    if (std::abs(p.y - (a + b * p.x)) <= tol) in.push_back(p);
  return in;
}

}  // namespace

std::optional<ReflectorLine> FindReflectorLine(std::span<const std::uint8_t> pixels, int width,
                                               int height, const ReflectorLineOptions& o) {
  if (width < 3 || height < 3 ||
      pixels.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    throw std::invalid_argument("FindReflectorLine: frame of " + std::to_string(pixels.size()) +
                                " pixels is not " + std::to_string(width) + " x " +
                                std::to_string(height) + " (both at least 3)");
  }
  if (!(o.peak_fraction > 0.0 && o.peak_fraction <= 1.0) || !(o.min_peak >= 0.0) ||
      !(o.inlier_px > 0.0) || !(o.min_inliers > 0.0 && o.min_inliers <= 1.0) ||
      o.ransac_iterations < 1 || o.skip_rows < 0 || o.skip_rows >= height - 2) {
    throw std::invalid_argument("FindReflectorLine: options out of range");
  }
  const auto at = [&](int x, int y) {
    return static_cast<double>(
        pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
               static_cast<std::size_t>(x)]);
  };
  double frame_max = 0.0;
  for (int y = o.skip_rows; y < height; ++y)
    for (int x = 0; x < width; ++x) frame_max = std::max(frame_max, at(x, y));
  const double threshold = std::max(o.min_peak, o.peak_fraction * frame_max);

  // Per column: the brightest pixel, the run around it above half its value, and the
  // intensity centre of gravity of that run above the half level (sub-pixel depth).
  std::vector<RlPeak> peaks;
  for (int x = 0; x < width; ++x) {
    int best = o.skip_rows;
    for (int y = o.skip_rows + 1; y < height; ++y)
      if (at(x, y) > at(x, best)) best = y;
    const double peak = at(x, best);
    if (peak < threshold || peak <= 0.0) continue;
    const double half = 0.5 * peak;
    int lo = best, hi = best;
    while (lo > o.skip_rows && at(x, lo - 1) > half) --lo;
    while (hi < height - 1 && at(x, hi + 1) > half) ++hi;
    double sw = 0.0, swy = 0.0;
    for (int y = lo; y <= hi; ++y) {
      const double w = at(x, y) - half;
      sw += w;
      swy += w * y;
    }
    peaks.push_back({static_cast<double>(x), sw > 0.0 ? swy / sw : static_cast<double>(best)});
  }
  const auto needed = static_cast<std::size_t>(
      std::max(3.0, std::ceil(o.min_inliers * static_cast<double>(width))));
  if (peaks.size() < needed) return std::nullopt;

  // RANSAC over column pairs (a fixed pseudo-random sequence: the same frame gives the same
  // line), scored by inlier count, then by the inliers' residual sum.
  std::size_t best_count = 0;
  double best_cost = 0.0, best_a = 0.0, best_b = 0.0;
  std::uint64_t state = 0x9E3779B97F4A7C15ULL;
  const auto next = [&](std::size_t n) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<std::size_t>((state >> 33) % n);
  };
  for (int it = 0; it < o.ransac_iterations; ++it) {
    const std::size_t i = next(peaks.size());
    const std::size_t j = next(peaks.size());
    if (peaks[i].x == peaks[j].x) continue;
    const double b = (peaks[j].y - peaks[i].y) / (peaks[j].x - peaks[i].x);
    const double a = peaks[i].y - b * peaks[i].x;
    std::size_t count = 0;
    double cost = 0.0;
    for (const RlPeak& p : peaks) {
      const double r = std::abs(p.y - (a + b * p.x));
      if (r <= o.inlier_px) {
        ++count;
        cost += r;
      }
    }
    if (count > best_count || (count == best_count && cost < best_cost)) {
      best_count = count;
      best_cost = cost;
      best_a = a;
      best_b = b;
    }
  }
  if (best_count < needed) return std::nullopt;
  double a = best_a, b = best_b;
  std::vector<RlPeak> in = RlInliers(peaks, a, b, o.inlier_px);
  for (int refine = 0; refine < 2; ++refine) {
    if (!RlFitDepthLine(in, &a, &b)) return std::nullopt;
    in = RlInliers(peaks, a, b, o.inlier_px);
  }
  if (in.size() < needed || !RlFitDepthLine(in, &a, &b)) return std::nullopt;
  double ss = 0.0;
  for (const RlPeak& p : in) ss += (p.y - (a + b * p.x)) * (p.y - (a + b * p.x));
  ReflectorLine line;
  line.depth_px = a + b * 0.5 * (width - 1);
  line.slope = b;
  line.columns = static_cast<int>(peaks.size());
  line.inliers = static_cast<int>(in.size());
  line.rms_px = std::sqrt(ss / static_cast<double>(in.size()));
  return line;
}

}  // namespace echoservo::tracking
