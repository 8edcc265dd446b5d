#include "tracking/axis_profile.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "tracking/radon_transform.h"

namespace echoservo::tracking {
namespace {

// Max of Sample() over a small disc ⟂ the axis at s.
double ProfileAt(const imaging::Volume& v, const Line3& l, double s, const Eigen::Vector3d& u,
                 const Eigen::Vector3d& w, double r) {
  const Eigen::Vector3d c = l.point + s * l.direction;
  double m = v.Sample(c);
  if (std::isnan(m)) return m;
  for (int k = 0; k < 8; ++k) {
    const double a = k * std::numbers::pi / 4;
    const double x = v.Sample(c + r * (std::cos(a) * u + std::sin(a) * w));
    if (!std::isnan(x)) m = std::max(m, x);
  }
  return m;
}

// Log-compressed display value (0–255 over `dynamic_range_db`) → echo amplitude (relative).
double Amplitude(double display, double dynamic_range_db) {
  return std::pow(10.0, display / 255.0 * dynamic_range_db / 20.0);
}

}  // namespace

TipEstimate FindTip(const imaging::Volume& v, const Line3& axis, double bg, const EdgeOptions& edge) {
  const double tip_fraction = edge.edge_fraction;
  auto A = [&](double x) { return Amplitude(x, edge.dynamic_range_db); };
  TipEstimate out;
  Line3 line = axis;
  // Intensity profile along the axis.
  Eigen::Vector3d u, w;
  PlaneBasis(line.direction, u, w);
  const auto box = v.BoundingBoxMm();
  const double ext = 0.5 * box.diagonal().norm() + 1;
  const double s_c = line.Parameter(box.center());
  const double ds = 0.25;
  std::vector<double> s_val, prof;
  for (double s = s_c - ext; s <= s_c + ext; s += ds) {
    s_val.push_back(s);
    prof.push_back(ProfileAt(v, line, s, u, w, 0.6));
  }
  const int N = static_cast<int>(prof.size());
  // Smooth (1 mm box) ignoring NaN; zero (outside the scan) counts as invalid too.
  std::vector<double> sm(static_cast<std::size_t>(N), std::numeric_limits<double>::quiet_NaN());
  for (int i = 0; i < N; ++i) {
    double sum = 0;
    int n = 0;
    for (int t = -2; t <= 2; ++t) {
      const int q = i + t;
      if (q < 0 || q >= N || std::isnan(prof[static_cast<std::size_t>(q)])) continue;
      sum += prof[static_cast<std::size_t>(q)];
      ++n;
    }
    if (n > 0 && !std::isnan(prof[static_cast<std::size_t>(i)]) && prof[static_cast<std::size_t>(i)] > 0) sm[static_cast<std::size_t>(i)] = sum / n;
  }
  std::vector<double> valid;
  for (double x : sm) if (!std::isnan(x)) valid.push_back(x);
  if (valid.size() < 8) return out;
  std::sort(valid.begin(), valid.end());
  const double p90 = valid[valid.size() * 9 / 10];
  if (p90 <= bg + 10) return out;
  const double thr = bg + 0.3 * (p90 - bg);
  // Longest run above thr allowing 2 mm gaps.
  int best_a = -1, best_b = -1, a = -1, last = -1;
  const int gap = static_cast<int>(2.0 / ds);
  for (int i = 0; i < N; ++i) {
    const double x = sm[static_cast<std::size_t>(i)];
    if (!std::isnan(x) && x >= thr) {
      if (a < 0 || i - last > gap) a = i;
      last = i;
      if (best_a < 0 || last - a > best_b - best_a) { best_a = a; best_b = last; }
    }
  }
  if (best_a < 0) return out;
  out.line_length_mm = (best_b - best_a) * ds;
  // Which end is the entry: the one nearer the edge of the valid (scanned) region.
  int first_valid = 0, last_valid = N - 1;
  while (first_valid < N && std::isnan(sm[static_cast<std::size_t>(first_valid)])) ++first_valid;
  while (last_valid >= 0 && std::isnan(sm[static_cast<std::size_t>(last_valid)])) --last_valid;
  const bool tip_high = (best_a - first_valid) <= (last_valid - best_b);
  const int tip_i = tip_high ? best_b : best_a;
  const int step = tip_high ? 1 : -1;
  // Local running level inside the run near the tip (3 mm), then the crossing of
  // bg + tip_fraction·(level − bg) going outward.
  std::vector<double> loc;
  for (int t = 0; t < static_cast<int>(3.0 / ds); ++t) {
    const int q = tip_i - step * t;
    if (q < best_a || q > best_b) break;
    if (!std::isnan(sm[static_cast<std::size_t>(q)])) loc.push_back(sm[static_cast<std::size_t>(q)]);
  }
  std::sort(loc.begin(), loc.end());
  const double level = loc.empty() ? p90 : loc[loc.size() / 2];
  const double cut = A(bg) + tip_fraction * (A(level) - A(bg));
  double tip_s = s_val[static_cast<std::size_t>(tip_i)];
  {
    // From inside the run (3 mm back from its end), outward to the first sample below cut.
    int q = tip_i;
    for (int t = 0; t < static_cast<int>(3.0 / ds) && q - step >= best_a && q - step <= best_b; ++t) q -= step;
    while (q + step >= 0 && q + step < N && !std::isnan(sm[static_cast<std::size_t>(q + step)]) &&
           A(prof[static_cast<std::size_t>(q + step)]) >= cut)
      q += step;
    const int r = q + step;
    tip_s = s_val[static_cast<std::size_t>(q)];
    if (r >= 0 && r < N && !std::isnan(prof[static_cast<std::size_t>(r)])) {
      const double x0 = A(prof[static_cast<std::size_t>(q)]), x1 = A(prof[static_cast<std::size_t>(r)]);
      if (x0 > x1) tip_s += step * ds * std::clamp((x0 - cut) / (x0 - x1), 0.0, 1.0);
    }
  }
  if (!tip_high) line.direction = -line.direction;
  const double sgn = tip_high ? 1.0 : -1.0;
  // Re-express: parameter along the new direction.
  out.axis = line;
  out.tip_mm = line.point + sgn * tip_s * line.direction;

  out.line_level = level;
  out.found = true;
  return out;
}

TargetEstimate FindTarget(const imaging::Volume& v, const TipEstimate& tip, double bg,
                          const EdgeOptions& edge) {
  auto A = [&](double x) { return Amplitude(x, edge.dynamic_range_db); };
  TargetEstimate out;
  const Line3 line = tip.axis;
  const double level = tip.line_level;
  const double ds = 0.25;
  const double ext = 0.5 * v.BoundingBoxMm().diagonal().norm() + 1;
  // Target: forward from the tip, first rise above background after a gap.
  {
    std::vector<double> fp;
    const Line3 fwd{tip.tip_mm, line.direction};
    Eigen::Vector3d fu, fw;
    PlaneBasis(fwd.direction, fu, fw);
    for (double s = 0; s <= ext * 2; s += ds) {
      const double x = ProfileAt(v, fwd, s, fu, fw, 0.75);
      if (std::isnan(x)) break;
      fp.push_back(x);
    }
    const int M = static_cast<int>(fp.size());
    std::vector<double> fs(static_cast<std::size_t>(M), 0);
    for (int i = 0; i < M; ++i) {
      double sum = 0;
      int n = 0;
      for (int t = -2; t <= 2; ++t)
        if (i + t >= 0 && i + t < M) { sum += fp[static_cast<std::size_t>(i + t)]; ++n; }
      fs[static_cast<std::size_t>(i)] = sum / n;
    }
    const int start = static_cast<int>(2.0 / ds);
    // Background just past the tip gap.
    // Background just past the tip gap: median over the next 4 mm.
    double fbg = bg;
    {
      std::vector<double> near;
      for (int i = start; i < std::min(M, start + static_cast<int>(4.0 / ds)); ++i) near.push_back(fs[static_cast<std::size_t>(i)]);
      if (!near.empty()) {
        std::nth_element(near.begin(), near.begin() + static_cast<long>(near.size() / 2), near.end());
        fbg = near[near.size() / 2];
      }
    }
    const double rise = std::max(12.0, 0.1 * (level - bg));
    for (int i = start; i < M; ++i) {
      if (fs[static_cast<std::size_t>(i)] > fbg + rise) {
        // Peak of the rise within the next 3 mm, then the half-maximum crossing backwards.
        int pk = i;
        for (int t = i; t < std::min(M, i + static_cast<int>(3.0 / ds)); ++t)
          if (fs[static_cast<std::size_t>(t)] > fs[static_cast<std::size_t>(pk)]) pk = t;
        // An interface images as the point-spread function centred on it: the target is the
        // peak of the first echo (parabolic sub-sample refinement in amplitude).
        double s = pk * ds;
        if (pk > 0 && pk + 1 < M) {
          const double y0 = A(fs[static_cast<std::size_t>(pk - 1)]), y1 = A(fs[static_cast<std::size_t>(pk)]),
                       y2 = A(fs[static_cast<std::size_t>(pk + 1)]);
          const double den = y0 - 2 * y1 + y2;
          if (den < 0) s += ds * std::clamp(0.5 * (y0 - y2) / den, -0.5, 0.5);
        }
        out.found = true;
        out.target_mm = tip.tip_mm + s * line.direction;
        break;
      }
    }
  }

  return out;
}

}  // namespace echoservo::tracking
