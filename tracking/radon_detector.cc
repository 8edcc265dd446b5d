#include "tracking/radon_detector.h"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

namespace echoservo::tracking {
namespace {

struct Cell {
  Eigen::Vector3d p;  // mm
  double w;           // (value − background)², > 0
};

// One resolution level: the weighted non-background cells.
struct Level {
  std::vector<Cell> cells;
  double bin_mm = 1.0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double half_extent = 1.0;
  double max_z = 0.0;  // deepest line point considered (far-field walls lie beyond)
};

double MedianNonZero(const imaging::Volume& v) {
  std::array<std::int64_t, 256> h{};
  for (auto x : v.voxels()) ++h[x];
  std::int64_t n = 0;
  for (int i = 1; i < 256; ++i) n += h[static_cast<std::size_t>(i)];
  if (n == 0) return 0.0;
  std::int64_t acc = 0;
  for (int i = 1; i < 256; ++i) {
    acc += h[static_cast<std::size_t>(i)];
    if (2 * acc >= n) return i;
  }
  return 255.0;
}

Level MakeLevel(const imaging::Volume& v, int f, double max_depth_fraction) {
  Level L;
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
    if (2 * acc >= cnt) { bg = i; break; }
  }
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) {
        const double x = pooled[static_cast<std::size_t>(i) + static_cast<std::size_t>(n.x()) *
                                    (static_cast<std::size_t>(j) + static_cast<std::size_t>(n.y()) * k)];
        if (x <= bg) continue;
        const Eigen::Vector3d idx(std::min<double>(i * f + 0.5 * (f - 1), d.x() - 1),
                                  std::min<double>(j * f + 0.5 * (f - 1), d.y() - 1),
                                  std::min<double>(k * f + 0.5 * (f - 1), d.z() - 1));
        L.cells.push_back({v.IndexToPhysical(idx), (x - bg) * (x - bg)});
      }
  L.bin_mm = f * std::cbrt(v.spacing_mm().prod());
  const auto box = v.BoundingBoxMm();
  L.centre = box.center();
  L.half_extent = 0.5 * box.diagonal().norm() + 2 * L.bin_mm;
  L.max_z = box.min().z() + max_depth_fraction * (box.max().z() - box.min().z());
  return L;
}

void Basis(const Eigen::Vector3d& d, Eigen::Vector3d& u, Eigen::Vector3d& w) {
  u = d.unitOrthogonal();
  w = d.cross(u).normalized();
}

struct Peak {
  double score = -1;   // contrast of the peak against its ring
  double a = 0, c = 0; // offset in the (u, w) plane, mm from the level centre
  double z = 0;        // robust z-score of the peak among the histogram's bins
};

// Radon histogram for direction d; all local-max peaks with their contrast.
std::vector<Peak> RadonPeaks(const Level& L, const Eigen::Vector3d& d, const Line3* window,
                             double window_mm, bool want_z) {
  const double max_z = L.max_z;
  Eigen::Vector3d u, w;
  Basis(d, u, w);
  const int n = static_cast<int>(std::ceil(2 * L.half_extent / L.bin_mm)) + 1;
  std::vector<double> H(static_cast<std::size_t>(n) * n, 0.0);
  const double inv = 1.0 / L.bin_mm, off = 0.5 * (n - 1);
  for (const auto& c : L.cells) {
    const Eigen::Vector3d r = c.p - L.centre;
    const double x = r.dot(u) * inv + off, y = r.dot(w) * inv + off;
    const int ix = static_cast<int>(x), iy = static_cast<int>(y);
    if (ix < 0 || iy < 0 || ix >= n - 1 || iy >= n - 1) continue;
    const double fx = x - ix, fy = y - iy;
    double* h = &H[static_cast<std::size_t>(iy) * n + ix];
    h[0] += c.w * (1 - fx) * (1 - fy);
    h[1] += c.w * fx * (1 - fy);
    h[n] += c.w * (1 - fx) * fy;
    h[n + 1] += c.w * fx * fy;
  }
  double wa = 0, wc = 0;
  if (window) {
    const Eigen::Vector3d r = window->point - L.centre;
    wa = r.dot(u);
    wc = r.dot(w);
  }
  std::vector<Peak> peaks;
  std::vector<double> all;
  for (int y = 2; y < n - 2; ++y)
    for (int x = 2; x < n - 2; ++x) {
      const double v = H[static_cast<std::size_t>(y) * n + x];
      if (v <= 0) continue;
      std::array<double, 16> ring{};
      int m = 0;
      for (int t = -2; t <= 2; ++t) {
        ring[static_cast<std::size_t>(m++)] = H[static_cast<std::size_t>(y - 2) * n + x + t];
        ring[static_cast<std::size_t>(m++)] = H[static_cast<std::size_t>(y + 2) * n + x + t];
      }
      for (int t = -1; t <= 1; ++t) {
        ring[static_cast<std::size_t>(m++)] = H[static_cast<std::size_t>(y + t) * n + x - 2];
        ring[static_cast<std::size_t>(m++)] = H[static_cast<std::size_t>(y + t) * n + x + 2];
      }
      const double score = v - *std::max_element(ring.begin(), ring.end());
      if (want_z) all.push_back(std::max(0.0, score));
      bool is_max = true;
      for (int dy = -1; dy <= 1 && is_max; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if ((dx || dy) && H[static_cast<std::size_t>(y + dy) * n + x + dx] > v) { is_max = false; break; }
      if (!is_max || score <= 0) continue;
      Peak p;
      p.score = score;
      // Parabolic sub-bin peak.
      auto at = [&](int xx, int yy) { return H[static_cast<std::size_t>(yy) * n + xx]; };
      const double dxd = at(x - 1, y) - 2 * v + at(x + 1, y), dyd = at(x, y - 1) - 2 * v + at(x, y + 1);
      const double sx = dxd < 0 ? std::clamp(0.5 * (at(x - 1, y) - at(x + 1, y)) / dxd, -0.5, 0.5) : 0.0;
      const double sy = dyd < 0 ? std::clamp(0.5 * (at(x, y - 1) - at(x, y + 1)) / dyd, -0.5, 0.5) : 0.0;
      p.a = (x + sx - off) * L.bin_mm;
      p.c = (y + sy - off) * L.bin_mm;
      if (window && std::hypot(p.a - wa, p.c - wc) > window_mm) continue;
      if ((L.centre + p.a * u + p.c * w).z() > max_z) continue;
      peaks.push_back(p);
    }
  std::sort(peaks.begin(), peaks.end(), [](const Peak& a, const Peak& b) { return a.score > b.score; });
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

Line3 PeakLine(const Level& L, const Eigen::Vector3d& d, const Peak& p) {
  Eigen::Vector3d u, w;
  Basis(d, u, w);
  return Line3{L.centre + p.a * u + p.c * w, d.normalized()};
}

std::vector<Eigen::Vector3d> Fibonacci(int n) {
  std::vector<Eigen::Vector3d> dirs;
  const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (i + 0.5) / n;  // hemisphere z ∈ (0, 1)
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    dirs.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  return dirs;
}

std::vector<Eigen::Vector3d> Cone(const Eigen::Vector3d& d, double half, int steps) {
  Eigen::Vector3d u, w;
  Basis(d, u, w);
  std::vector<Eigen::Vector3d> dirs;
  for (int i = 0; i < steps; ++i)
    for (int j = 0; j < steps; ++j) {
      const double a = steps > 1 ? -half + 2 * half * i / (steps - 1) : 0.0;
      const double b = steps > 1 ? -half + 2 * half * j / (steps - 1) : 0.0;
      dirs.push_back((d + std::tan(a) * u + std::tan(b) * w).normalized());
    }
  return dirs;
}

struct Best {
  Eigen::Vector3d d = Eigen::Vector3d::UnitZ();
  Peak peak;
  std::vector<double> scores;
};

Best Search(const Level& L, const std::vector<Eigen::Vector3d>& dirs, const Line3* window,
            double window_mm) {
  std::vector<Peak> best(dirs.size());
  tbb::parallel_for(std::size_t{0}, dirs.size(), [&](std::size_t i) {
    auto p = RadonPeaks(L, dirs[i], window, window_mm, false);
    if (!p.empty()) best[i] = p.front();
  });
  Best b;
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    b.scores.push_back(std::max(0.0, best[i].score));
    if (best[i].score > b.peak.score) {
      b.peak = best[i];
      b.d = dirs[i];
    }
  }
  return b;
}

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

}  // namespace

void RadonDetectorOptions::Validate() const {
  auto bad = [](const std::string& f) { throw std::invalid_argument("RadonDetectorOptions: bad " + f); };
  if (coarse_factor < 2 || coarse_factor > 16) bad("coarse_factor");
  if (coarse_directions < 16 || coarse_directions > 100000) bad("coarse_directions");
  if (!(fine_cone_rad > 0 && fine_cone_rad < 1)) bad("fine_cone_rad");
  if (fine_steps < 2 || fine_steps > 101) bad("fine_steps");
  if (!(fit_radius_mm > 0 && fit_radius_mm < 50)) bad("fit_radius_mm");
  if (!(tip_fraction > 0 && tip_fraction < 1)) bad("tip_fraction");
  if (!(min_line_length_mm >= 0 && std::isfinite(min_line_length_mm))) bad("min_line_length_mm");
  if (!(min_confidence >= 0 && min_confidence <= 1)) bad("min_confidence");
  if (!(tracking_cone_rad > 0 && tracking_cone_rad < 1.5)) bad("tracking_cone_rad");
  if (!(tracking_window_mm > 0 && std::isfinite(tracking_window_mm))) bad("tracking_window_mm");
  if (!(max_depth_fraction > 0 && max_depth_fraction <= 1)) bad("max_depth_fraction");
  if (!(max_spacing_ratio >= 1 && std::isfinite(max_spacing_ratio))) bad("max_spacing_ratio");
}

RadonDetector::RadonDetector(RadonDetectorOptions options) : options_(std::move(options)) {
  options_.Validate();
}

CatheterDetection RadonDetector::Detect(const imaging::Volume& volume) const {
  return Run(volume, nullptr);
}

CatheterDetection RadonDetector::Detect(const imaging::Volume& volume, const Line3& previous) const {
  auto r = Run(volume, &previous);
  if (r.found && r.confidence >= options_.min_confidence) return r;
  return Run(volume, nullptr);
}

CatheterDetection RadonDetector::Track(const imaging::Volume& volume) {
  auto r = previous_ ? Detect(volume, *previous_) : Detect(volume);
  if (r.found) previous_ = r.axis; else previous_.reset();
  return r;
}

CatheterDetection RadonDetector::Run(const imaging::Volume& v, const Line3* previous) const {
  CatheterDetection out;
  const Eigen::Vector3d sp = v.spacing_mm();
  if (sp.maxCoeff() > options_.max_spacing_ratio * sp.minCoeff())
    throw std::invalid_argument("RadonDetector: voxel spacing too anisotropic (max/min > " +
                                std::to_string(options_.max_spacing_ratio) + ")");
  if (v.dims().minCoeff() < 8) return out;
  const double bg = MedianNonZero(v);

  const int f1 = options_.coarse_factor, f2 = std::max(1, f1 / 2);
  const Level L1 = MakeLevel(v, f1, options_.max_depth_fraction);
  if (L1.cells.size() < 4) return out;
  const Level L2 = MakeLevel(v, f2, options_.max_depth_fraction);

  Best b;
  double window_mm = std::numeric_limits<double>::infinity();
  const Line3* window = nullptr;
  if (previous) {
    window = previous;
    window_mm = options_.tracking_window_mm;
    Eigen::Vector3d pd = previous->direction;
    if (pd.z() < 0) pd = -pd;
    const int steps = std::max(3, static_cast<int>(std::ceil(2 * options_.tracking_cone_rad / 0.03)) | 1);
    b = Search(L1, Cone(pd, options_.tracking_cone_rad, steps), window, window_mm);
  } else {
    b = Search(L1, Fibonacci(options_.coarse_directions), nullptr, window_mm);
  }
  if (b.peak.score <= 0) return out;
  // Refine at the finer level, near the coarse line.
  Line3 coarse = PeakLine(L1, b.d, b.peak);
  double cone = options_.fine_cone_rad;
  Best f = b;
  for (int pass = 0; pass < 2; ++pass) {
    Best g = Search(L2, Cone(f.d, cone, options_.fine_steps), &coarse, 2 * L1.bin_mm);
    if (g.peak.score > 0) {
      f = g;
      coarse = PeakLine(L2, f.d, f.peak);
    }
    cone /= (options_.fine_steps - 1) / 2.0;
  }
  // Shallowest strong line among the parallel candidates of the best direction.
  auto peaks = RadonPeaks(L2, f.d, window, window_mm, true);
  if (peaks.empty()) return out;
  double z_score = 0;
  {
    // The distribution of line scores over the hemisphere (a sparse set when tracking: the
    // cone's directions all see the line).
    std::vector<double> sc = previous ? Search(L1, Fibonacci(std::max(16, options_.coarse_directions / 8)), nullptr,
                                               std::numeric_limits<double>::infinity()).scores
                                      : b.scores;
    auto mid = sc.begin() + static_cast<long>(sc.size() / 2);
    std::nth_element(sc.begin(), mid, sc.end());
    const double med = *mid;
    for (auto& x : sc) x = std::abs(x - med);
    std::nth_element(sc.begin(), mid, sc.end());
    const double mad = 1.4826 * (*mid);
    z_score = (b.peak.score - med) / (mad + 1e-3 * b.peak.score + 1e-12);
  }
  Line3 line = PeakLine(L2, f.d, peaks.front());
  for (const auto& p : peaks) {
    if (p.score < 0.6 * peaks.front().score) break;
    const Line3 cand = PeakLine(L2, f.d, p);
    if (cand.point.z() < line.point.z() - 1.0 && std::abs(cand.point.z() - line.point.z()) < 15.0) line = cand;
  }

  // Full-resolution IRLS fit of voxels near the line, weighted by (value − background)².
  for (double radius : {options_.fit_radius_mm, 0.8 * options_.fit_radius_mm, 0.6 * options_.fit_radius_mm}) {
    std::vector<Eigen::Vector3d> pts;
    std::vector<double> wts;
    // Walk along the line through the volume.
    const Eigen::Vector3i dims = v.dims();
    const int shadow_k = static_cast<int>(std::lround(options_.first_echo_mm / sp.z()));
    // Bounding index range of the cylinder: simple full scan restricted to the line's slab.
    for (int k = 0; k < dims.z(); ++k)
      for (int j = 0; j < dims.y(); ++j) {
        const Eigen::Vector3d row0 = v.IndexToPhysical(Eigen::Vector3d(0, j, k));
        const Eigen::Vector3d r0 = row0 - line.point;
        const Eigen::Vector3d dx = v.direction().col(0) * sp.x();
        // distance² along the row is quadratic in i: find the min and the range within radius.
        const Eigen::Vector3d a = r0 - r0.dot(line.direction) * line.direction;
        const Eigen::Vector3d e = dx - dx.dot(line.direction) * line.direction;
        const double ee = e.squaredNorm(), ae = a.dot(e), aa = a.squaredNorm();
        int i0 = 0, i1 = dims.x() - 1;
        if (ee > 1e-12) {
          const double disc = ae * ae - ee * (aa - radius * radius);
          if (disc < 0) continue;
          const double sq = std::sqrt(disc);
          i0 = std::max(0, static_cast<int>(std::ceil((-ae - sq) / ee)));
          i1 = std::min(dims.x() - 1, static_cast<int>(std::floor((-ae + sq) / ee)));
        } else if (aa > radius * radius) {
          continue;
        }
        for (int i = i0; i <= i1; ++i) {
          const double x = v.at(i, j, k);
          if (x <= bg) continue;
          if (shadow_k > 0) {
            // Reverberation tails and the far side of the sheath lie deeper along the beam
            // (image z) than a brighter echo: keep only the first echo of each column.
            bool behind = false;
            for (int q = std::max(0, k - shadow_k); q < k && !behind; ++q) behind = v.at(i, j, q) > x;
            if (behind) continue;
          }
          pts.push_back(row0 + i * dx);
          wts.push_back((x - bg) * (x - bg));
        }
      }
    if (pts.size() < 4) return out;
    try {
      line = FitLine(pts, wts);
    } catch (const std::invalid_argument&) {
      return out;
    }
  }

  // Intensity profile along the axis.
  Eigen::Vector3d u, w;
  Basis(line.direction, u, w);
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
  const double cut = bg + options_.tip_fraction * (level - bg);
  double tip_s = s_val[static_cast<std::size_t>(tip_i)];
  {
    int q = tip_i;
    while (q + step >= 0 && q + step < N && !std::isnan(sm[static_cast<std::size_t>(q + step)]) &&
           sm[static_cast<std::size_t>(q + step)] >= cut)
      q += step;
    const int r = q + step;
    tip_s = s_val[static_cast<std::size_t>(q)];
    if (r >= 0 && r < N && !std::isnan(sm[static_cast<std::size_t>(r)])) {
      const double x0 = sm[static_cast<std::size_t>(q)], x1 = sm[static_cast<std::size_t>(r)];
      if (x0 > x1) tip_s += step * ds * std::clamp((x0 - cut) / (x0 - x1), 0.0, 1.0);
    }
  }
  if (!tip_high) line.direction = -line.direction;
  const double sgn = tip_high ? 1.0 : -1.0;
  // Re-express: parameter along the new direction.
  out.axis = line;
  out.tip_mm = line.point + sgn * tip_s * line.direction;

  // Target: forward from the tip, first rise above background after a gap.
  {
    std::vector<double> fp;
    const Line3 fwd{out.tip_mm, line.direction};
    Eigen::Vector3d fu, fw;
    Basis(fwd.direction, fu, fw);
    for (double s = 0; s <= ext * 2; s += ds) {
      const double x = ProfileAt(v, fwd, s, fu, fw, 1.5);
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
        const double half = fbg + 0.5 * (fs[static_cast<std::size_t>(pk)] - fbg);
        int q = pk;
        while (q > start && fs[static_cast<std::size_t>(q - 1)] >= half) --q;
        double s = q * ds;
        if (q > 0) {
          const double x0 = fs[static_cast<std::size_t>(q - 1)], x1 = fs[static_cast<std::size_t>(q)];
          if (x1 > x0) s -= ds * std::clamp((x1 - half) / (x1 - x0), 0.0, 1.0);
        }
        out.target_found = true;
        out.target_mm = out.tip_mm + s * line.direction;
        break;
      }
    }
  }

  // Confidence: Radon peak contrast (robust z among the histogram's line integrals) and length.
  const double c_peak = 1.0 - std::exp(-std::max(0.0, z_score - 10.0) / 8.0);
  const double c_len = std::clamp(out.line_length_mm / (2.0 * std::max(1e-9, options_.min_line_length_mm)), 0.0, 1.0);
  out.confidence = std::clamp(c_peak * c_len, 0.0, 1.0);
  out.tracked = previous != nullptr;
  out.found = out.confidence >= options_.min_confidence && out.line_length_mm >= options_.min_line_length_mm;
  out.peak_z = z_score;
  return out;
}

}  // namespace echoservo::tracking
