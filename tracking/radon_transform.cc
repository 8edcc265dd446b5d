#include "tracking/radon_transform.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>

namespace echoservo::tracking {

RadonLevel MakeRadonLevel(const imaging::Volume& v, int f, double max_depth_fraction) {
  RadonLevel L;
  f = std::max(1, f);
  const Eigen::Vector3i d = v.dims();
  const Eigen::Vector3i n((d.x() + f - 1) / f, (d.y() + f - 1) / f, (d.z() + f - 1) / f);
  std::vector<std::uint8_t> pooled(static_cast<std::size_t>(n.x()) * n.y() * n.z(), 0);
  for (int k = 0; k < d.z(); ++k)
    for (int j = 0; j < d.y(); ++j)
      for (int i = 0; i < d.x(); ++i) {
        auto& c = pooled[static_cast<std::size_t>(i / f) +
                         static_cast<std::size_t>(n.x()) * (static_cast<std::size_t>(j / f) +
                                                            static_cast<std::size_t>(n.y()) * (k / f))];
        c = std::max(c, v.at(i, j, k));
      }
  std::array<std::int64_t, 256> h{};
  for (auto x : pooled) ++h[x];
  std::int64_t cnt = 0;
  for (int i = 1; i < 256; ++i) cnt += h[static_cast<std::size_t>(i)];
  double bg = 0;
  std::int64_t acc = 0;
  for (int i = 1; i < 256 && cnt > 0; ++i) {
    acc += h[static_cast<std::size_t>(i)];
    if (2 * acc >= cnt) {
      bg = i;
      break;
    }
  }
  L.background = bg;
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) {
        const double x = pooled[static_cast<std::size_t>(i) +
                                static_cast<std::size_t>(n.x()) *
                                    (static_cast<std::size_t>(j) + static_cast<std::size_t>(n.y()) * k)];
        if (x <= bg) continue;
        const Eigen::Vector3d idx(std::min<double>(i * f + 0.5 * (f - 1), d.x() - 1),
                                  std::min<double>(j * f + 0.5 * (f - 1), d.y() - 1),
                                  std::min<double>(k * f + 0.5 * (f - 1), d.z() - 1));
        L.cells.push_back({v.IndexToPhysical(idx), (x - bg) * (x - bg)});
      }
  L.bin_mm = f * std::cbrt(v.spacing_mm().prod());
  const auto box = v.BoundingBoxMm();
  L.centre_mm = box.center();
  L.half_extent_mm = 0.5 * box.diagonal().norm() + 2 * L.bin_mm;
  L.max_depth_z_mm = box.min().z() + max_depth_fraction * (box.max().z() - box.min().z());
  return L;
}

void PlaneBasis(const Eigen::Vector3d& d, Eigen::Vector3d& u, Eigen::Vector3d& w) {
  u = d.unitOrthogonal();
  w = d.cross(u).normalized();
}

std::vector<RadonPeak> RadonPeaks(const RadonLevel& L, const Eigen::Vector3d& d,
                                  const RadonWindow* window, bool want_z) {
  Eigen::Vector3d u, w;
  PlaneBasis(d, u, w);
  const int n = static_cast<int>(std::ceil(2 * L.half_extent_mm / L.bin_mm)) + 1;
  std::vector<double> H(static_cast<std::size_t>(n) * n, 0.0);
  const double inv = 1.0 / L.bin_mm, off = 0.5 * (n - 1);
  for (const auto& c : L.cells) {
    const Eigen::Vector3d r = c.p_mm - L.centre_mm;
    const double x = r.dot(u) * inv + off, y = r.dot(w) * inv + off;
    const int ix = static_cast<int>(x), iy = static_cast<int>(y);
    if (ix < 0 || iy < 0 || ix >= n - 1 || iy >= n - 1) continue;
    const double fx = x - ix, fy = y - iy;
    double* h = &H[static_cast<std::size_t>(iy) * n + ix];
    h[0] += c.weight * (1 - fx) * (1 - fy);
    h[1] += c.weight * fx * (1 - fy);
    h[n] += c.weight * (1 - fx) * fy;
    h[n + 1] += c.weight * fx * fy;
  }
  double wa = 0, wc = 0;
  if (window) {
    const Eigen::Vector3d r = window->line.point - L.centre_mm;
    wa = r.dot(u);
    wc = r.dot(w);
  }
  auto at = [&](int xx, int yy) { return H[static_cast<std::size_t>(yy) * n + xx]; };
  std::vector<RadonPeak> peaks;
  std::vector<double> all;
  for (int y = 2; y < n - 2; ++y)
    for (int x = 2; x < n - 2; ++x) {
      const double v = at(x, y);
      if (v <= 0) continue;
      double ring = 0;
      for (int t = -2; t <= 2; ++t) ring = std::max({ring, at(x + t, y - 2), at(x + t, y + 2)});
      for (int t = -1; t <= 1; ++t) ring = std::max({ring, at(x - 2, y + t), at(x + 2, y + t)});
      const double score = v - ring;
      if (want_z) all.push_back(std::max(0.0, score));
      bool is_max = true;
      for (int dy = -1; dy <= 1 && is_max; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if ((dx || dy) && at(x + dx, y + dy) > v) {
            is_max = false;
            break;
          }
      if (!is_max || score <= 0) continue;
      RadonPeak p;
      p.score = score;
      // Parabolic sub-bin peak.
      const double dxd = at(x - 1, y) - 2 * v + at(x + 1, y), dyd = at(x, y - 1) - 2 * v + at(x, y + 1);
      const double sx = dxd < 0 ? std::clamp(0.5 * (at(x - 1, y) - at(x + 1, y)) / dxd, -0.5, 0.5) : 0.0;
      const double sy = dyd < 0 ? std::clamp(0.5 * (at(x, y - 1) - at(x, y + 1)) / dyd, -0.5, 0.5) : 0.0;
      p.a_mm = (x + sx - off) * L.bin_mm;
      p.c_mm = (y + sy - off) * L.bin_mm;
      if (window && std::hypot(p.a_mm - wa, p.c_mm - wc) > window->radius_mm) continue;
      if ((L.centre_mm + p.a_mm * u + p.c_mm * w).z() > L.max_depth_z_mm) continue;
      peaks.push_back(p);
    }
  std::sort(peaks.begin(), peaks.end(), [](const RadonPeak& a, const RadonPeak& b) { return a.score > b.score; });
  if (want_z && !peaks.empty() && all.size() > 8) {
    auto mid = all.begin() + static_cast<long>(all.size() / 2);
    std::nth_element(all.begin(), mid, all.end());
    const double med = *mid;
    for (auto& x : all) x = std::abs(x - med);
    std::nth_element(all.begin(), mid, all.end());
    const double mad = 1.4826 * (*mid) + 1e-9 * peaks.front().score + 1e-12;
    peaks.front().z = (peaks.front().score - med) / mad;
  }
  return peaks;
}

Line3 PeakLine(const RadonLevel& L, const Eigen::Vector3d& d, const RadonPeak& p) {
  Eigen::Vector3d u, w;
  PlaneBasis(d, u, w);
  return Line3{L.centre_mm + p.a_mm * u + p.c_mm * w, d.normalized()};
}

std::vector<Eigen::Vector3d> FibonacciHemisphere(int n) {
  std::vector<Eigen::Vector3d> dirs;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (i + 0.5) / n;  // hemisphere z ∈ (0, 1)
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    dirs.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  return dirs;
}

std::vector<Eigen::Vector3d> DirectionCone(const Eigen::Vector3d& d, double half, int steps) {
  Eigen::Vector3d u, w;
  PlaneBasis(d, u, w);
  std::vector<Eigen::Vector3d> dirs;
  for (int i = 0; i < steps; ++i)
    for (int j = 0; j < steps; ++j) {
      const double a = steps > 1 ? -half + 2 * half * i / (steps - 1) : 0.0;
      const double b = steps > 1 ? -half + 2 * half * j / (steps - 1) : 0.0;
      dirs.push_back((d + std::tan(a) * u + std::tan(b) * w).normalized());
    }
  return dirs;
}

RadonSearchResult SearchDirections(const RadonLevel& L, std::span<const Eigen::Vector3d> dirs,
                                   const RadonWindow* window) {
  std::vector<RadonPeak> best(dirs.size());
  tbb::parallel_for(std::size_t{0}, dirs.size(), [&](std::size_t i) {
    auto p = RadonPeaks(L, dirs[i], window, false);
    if (!p.empty()) best[i] = p.front();
  });
  RadonSearchResult b;
  b.scores.reserve(dirs.size());
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    b.scores.push_back(std::max(0.0, best[i].score));
    if (best[i].score > b.peak.score) {
      b.peak = best[i];
      b.direction = dirs[i];
    }
  }
  return b;
}

}  // namespace echoservo::tracking
