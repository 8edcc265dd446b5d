#include "tracking/ransac_line_detector.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

namespace echoservo::tracking {
namespace {

struct BrightVoxels {
  std::vector<Eigen::Vector3d> p_mm;
  std::vector<double> value;
};

// Quantile q of the non-zero voxel values from their histogram (h[0] ignored).
int HistogramQuantile(const std::array<std::int64_t, 256>& h, std::int64_t n, double q) {
  std::int64_t acc = 0;
  for (int i = 1; i < 256; ++i) {
    acc += h[static_cast<std::size_t>(i)];
    if (static_cast<double>(acc) >= q * static_cast<double>(n)) return i;
  }
  return 255;
}

BrightVoxels Threshold(const imaging::Volume& v, const RansacLineDetectorOptions& o) {
  std::array<std::int64_t, 256> h{};
  for (auto x : v.voxels()) ++h[x];
  std::int64_t n = 0;
  int vmax = 0;
  for (int i = 1; i < 256; ++i) {
    n += h[static_cast<std::size_t>(i)];
    if (h[static_cast<std::size_t>(i)] > 0) vmax = i;
  }
  BrightVoxels out;
  if (n == 0) return out;
  const int median = HistogramQuantile(h, n, 0.5);
  std::array<std::int64_t, 256> dev{};
  for (int i = 1; i < 256; ++i)
    dev[static_cast<std::size_t>(std::abs(i - median))] += h[static_cast<std::size_t>(i)];
  std::int64_t acc = 0;
  int mad = 0;
  for (int i = 0; i < 256; ++i) {
    acc += dev[static_cast<std::size_t>(i)];
    if (2 * acc >= n) {
      mad = i;
      break;
    }
  }
  const double t =
      std::min<double>(vmax, std::max<double>(HistogramQuantile(h, n, o.threshold_quantile),
                                              median + o.threshold_mad_k * 1.4826 * mad));
  const Eigen::Vector3i d = v.dims();
  for (int k = 0; k < d.z(); ++k)
    for (int j = 0; j < d.y(); ++j)
      for (int i = 0; i < d.x(); ++i) {
        const double x = v.at(i, j, k);
        if (x < t || x <= median) continue;
        out.p_mm.push_back(v.IndexToPhysical(Eigen::Vector3d(i, j, k)));
        out.value.push_back(x);
      }
  return out;
}

int FindRoot(std::vector<int>& parent, int i) {
  while (parent[static_cast<std::size_t>(i)] != i) {
    parent[static_cast<std::size_t>(i)] =
        parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    i = parent[static_cast<std::size_t>(i)];
  }
  return i;
}

// Drops the bright voxels of broad components: points are binned into cells of
// component_cell_mm, occupied cells joined with their 26 neighbours, and a component whose
// middle principal standard deviation exceeds max_component_sigma_mm (a surface or a slab,
// e.g. the tank floor; a line or a tube has two small ones) is removed.
BrightVoxels DropSurfaces(const BrightVoxels& pts, const RansacLineDetectorOptions& o) {
  if (o.max_component_sigma_mm <= 0) return pts;
  const double inv = 1.0 / o.component_cell_mm;
  auto key = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    return ((x + (1 << 20)) << 42) | ((y + (1 << 20)) << 21) | (z + (1 << 20));
  };
  std::unordered_map<std::int64_t, int> cell_of;
  std::vector<Eigen::Vector3i> cells;
  std::vector<int> point_cell(pts.p_mm.size());
  for (std::size_t i = 0; i < pts.p_mm.size(); ++i) {
    const Eigen::Vector3i c = (pts.p_mm[i] * inv).array().floor().cast<int>();
    const auto [it, added] =
        cell_of.emplace(key(c.x(), c.y(), c.z()), static_cast<int>(cells.size()));
    if (added) cells.push_back(c);
    point_cell[i] = it->second;
  }
  std::vector<int> parent(cells.size());
  for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<int>(i);
  for (std::size_t i = 0; i < cells.size(); ++i)
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const auto it =
              cell_of.find(key(cells[i].x() + dx, cells[i].y() + dy, cells[i].z() + dz));
          if (it == cell_of.end()) continue;
          const int a = FindRoot(parent, static_cast<int>(i)), b = FindRoot(parent, it->second);
          if (a != b) parent[static_cast<std::size_t>(a)] = b;
        }
  struct Moments {
    double n = 0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  };
  std::unordered_map<int, Moments> comp;
  std::vector<int> point_comp(pts.p_mm.size());
  for (std::size_t i = 0; i < pts.p_mm.size(); ++i) {
    point_comp[i] = FindRoot(parent, point_cell[i]);
    Moments& m = comp[point_comp[i]];
    m.n += 1;
    m.sum += pts.p_mm[i];
    m.outer += pts.p_mm[i] * pts.p_mm[i].transpose();
  }
  std::unordered_map<int, bool> keep;
  for (const auto& [id, m] : comp) {
    const Eigen::Vector3d mean = m.sum / m.n;
    const Eigen::Matrix3d cov = m.outer / m.n - mean * mean.transpose();
    const Eigen::Vector3d ev =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov, Eigen::EigenvaluesOnly).eigenvalues();
    keep[id] =
        std::sqrt(std::max(0.0, ev(1))) <= o.max_component_sigma_mm;  // ascending: ev(1) middle
  }
  BrightVoxels out;
  for (std::size_t i = 0; i < pts.p_mm.size(); ++i) {
    if (!keep[point_comp[i]]) continue;
    out.p_mm.push_back(pts.p_mm[i]);
    out.value.push_back(pts.value[i]);
  }
  return out;
}

// Best two-point hypothesis by score (inliers − shell_penalty × shell points) on a random
// subset of the points.
Line3 RansacLine(const BrightVoxels& pts, const RansacLineDetectorOptions& o,
                 std::mt19937_64& rng) {
  std::vector<std::size_t> idx(pts.p_mm.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  const std::size_t m = std::min(idx.size(), static_cast<std::size_t>(o.max_points));
  for (std::size_t i = 0; i < m; ++i) {  // partial Fisher–Yates: the first m are the subset
    std::uniform_int_distribution<std::size_t> pick(i, idx.size() - 1);
    std::swap(idx[i], idx[pick(rng)]);
  }
  std::vector<Eigen::Vector3d> sub(m);
  for (std::size_t i = 0; i < m; ++i) sub[i] = pts.p_mm[idx[i]];
  std::uniform_int_distribution<std::size_t> any(0, m - 1);
  const double r2 = o.inlier_radius_mm * o.inlier_radius_mm;
  const double sep2 = o.min_sample_separation_mm * o.min_sample_separation_mm;
  Line3 best = Line3::Through(sub[0], Eigen::Vector3d::UnitX());
  double best_count = -std::numeric_limits<double>::infinity();
  const double far2 = o.max_sample_separation_mm * o.max_sample_separation_mm;
  std::vector<std::size_t> near;
  for (int it = 0; it < o.iterations; ++it) {
    // Local sampling (NAPSAC): the second point among those sep..max_sep from the first, so
    // a small structure (the catheter, a few % of the bright voxels) still gets hypotheses.
    const Eigen::Vector3d& a = sub[any(rng)];
    near.clear();
    for (std::size_t i = 0; i < m; ++i) {
      const double d2 = (sub[i] - a).squaredNorm();
      if (d2 >= std::max(sep2, 1e-12) && d2 <= far2) near.push_back(i);
    }
    if (near.empty()) continue;
    const Eigen::Vector3d& b =
        sub[near[std::uniform_int_distribution<std::size_t>(0, near.size() - 1)(rng)]];
    const Eigen::Vector3d dir = (b - a).normalized();
    double count = 0;
    for (const auto& p : sub) {
      const Eigen::Vector3d r = p - a;
      const double d2 = (r - r.dot(dir) * dir).squaredNorm();
      if (d2 < r2) {
        count += 1;
      } else if (d2 < 4 * r2) {
        count -= o.shell_penalty;
      }
    }
    if (count > best_count) {
      best_count = count;
      best = Line3{a, dir};
    }
  }
  return best;
}

std::vector<std::size_t> Inliers(const BrightVoxels& pts, const Line3& line, double radius) {
  std::vector<std::size_t> in;
  for (std::size_t i = 0; i < pts.p_mm.size(); ++i)
    if (PointToLineDistance(line, pts.p_mm[i]) < radius) in.push_back(i);
  return in;
}

Line3 Refit(const BrightVoxels& pts, const std::vector<std::size_t>& in) {
  std::vector<Eigen::Vector3d> p;
  p.reserve(in.size());
  for (auto i : in) p.push_back(pts.p_mm[i]);
  return FitLine(p);
}

// The inliers of the longest run along the line (most inliers) with gaps ≤ max_gap.
std::vector<std::size_t> LongestRun(const BrightVoxels& pts, const Line3& line,
                                    std::vector<std::size_t> in, double max_gap) {
  std::sort(in.begin(), in.end(), [&](std::size_t a, std::size_t b) {
    return line.Parameter(pts.p_mm[a]) < line.Parameter(pts.p_mm[b]);
  });
  std::size_t best_a = 0, best_n = 0, a = 0;
  for (std::size_t i = 1; i <= in.size(); ++i) {
    const bool split =
        i == in.size() ||
        line.Parameter(pts.p_mm[in[i]]) - line.Parameter(pts.p_mm[in[i - 1]]) > max_gap;
    if (!split) continue;
    if (i - a > best_n) {
      best_n = i - a;
      best_a = a;
    }
    a = i;
  }
  return {in.begin() + static_cast<long>(best_a), in.begin() + static_cast<long>(best_a + best_n)};
}

// Distance from p outward along dir to the volume's bounding box.
double DistanceToBox(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& p,
                     const Eigen::Vector3d& dir) {
  double t = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (dir[a] > 1e-12) t = std::min(t, (box.max()[a] - p[a]) / dir[a]);
    if (dir[a] < -1e-12) t = std::min(t, (box.min()[a] - p[a]) / dir[a]);
  }
  return std::max(0.0, t);
}

double UpperMedian(std::vector<double> v) {
  auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

void FindTarget(const imaging::Volume& v, double level, const RansacLineDetectorOptions& o,
                CatheterDetection& d) {
  const double ds = 0.25;
  std::vector<double> ray;  // samples from target_start_mm on, until the volume ends
  for (double s = o.target_start_mm; s <= o.target_search_mm; s += ds) {
    const double x = v.Sample(d.tip_mm + s * d.axis.direction);
    if (std::isnan(x)) break;
    ray.push_back(x);
  }
  const std::size_t nbg = std::min(ray.size(), static_cast<std::size_t>(4.0 / ds));
  if (nbg == 0) return;
  const double bg =
      UpperMedian(std::vector<double>(ray.begin(), ray.begin() + static_cast<long>(nbg)));
  const double cut = bg + o.target_fraction * (level - bg);
  for (std::size_t i = 0; i < ray.size(); ++i) {
    if (ray[i] < cut || ray[i] <= bg) continue;
    double at = o.target_start_mm + static_cast<double>(i) * ds;
    if (i > 0 && ray[i] > ray[i - 1])
      at -= ds * std::min(1.0, (ray[i] - cut) / (ray[i] - ray[i - 1]));
    d.target_found = true;
    d.target_mm = d.tip_mm + at * d.axis.direction;
    return;
  }
}

}  // namespace

void RansacLineDetectorOptions::Validate() const {
  auto bad = [](const char* f) {
    std::string m = "RansacLineDetectorOptions: bad ";
    m += f;
    throw std::invalid_argument(m);
  };
  if (!(threshold_quantile >= 0.5 && threshold_quantile < 1)) bad("threshold_quantile");
  if (!(threshold_mad_k >= 0 && std::isfinite(threshold_mad_k))) bad("threshold_mad_k");
  if (max_points < 100) bad("max_points");
  if (iterations < 1) bad("iterations");
  if (!(inlier_radius_mm > 0 && std::isfinite(inlier_radius_mm))) bad("inlier_radius_mm");
  if (!(shell_penalty >= 0 && std::isfinite(shell_penalty))) bad("shell_penalty");
  if (!(min_sample_separation_mm >= 0 && std::isfinite(min_sample_separation_mm)))
    bad("min_sample_separation_mm");
  if (!(max_sample_separation_mm > min_sample_separation_mm &&
        std::isfinite(max_sample_separation_mm)))
    bad("max_sample_separation_mm");
  if (!(max_component_sigma_mm >= 0 && std::isfinite(max_component_sigma_mm)))
    bad("max_component_sigma_mm");
  if (!(component_cell_mm > 0 && std::isfinite(component_cell_mm))) bad("component_cell_mm");
  if (!(max_gap_mm > 0 && std::isfinite(max_gap_mm))) bad("max_gap_mm");
  if (min_inliers < 2) bad("min_inliers");
  if (!(min_line_length_mm >= 0 && std::isfinite(min_line_length_mm))) bad("min_line_length_mm");
  if (!(target_start_mm >= 0 && std::isfinite(target_start_mm))) bad("target_start_mm");
  if (!(target_search_mm > target_start_mm && std::isfinite(target_search_mm)))
    bad("target_search_mm");
  if (!(target_fraction > 0 && target_fraction <= 1)) bad("target_fraction");
}

RansacLineDetector::RansacLineDetector(RansacLineDetectorOptions options) : options_(options) {
  options_.Validate();
}

CatheterDetection RansacLineDetector::Detect(const imaging::Volume& v) const {
  const auto& o = options_;
  CatheterDetection d;
  if (v.dims().minCoeff() < 8) return d;
  const BrightVoxels pts = DropSurfaces(Threshold(v, o), o);
  if (pts.p_mm.size() < static_cast<std::size_t>(o.min_inliers)) return d;
  std::mt19937_64 rng(o.seed);
  Line3 line = RansacLine(pts, o, rng);
  std::vector<std::size_t> in;
  for (int pass = 0; pass < 2; ++pass) {  // TLS refit of the inliers, twice
    in = Inliers(pts, line, o.inlier_radius_mm);
    if (in.size() < static_cast<std::size_t>(o.min_inliers)) return d;
    line = Refit(pts, in);
  }
  in = LongestRun(pts, line, Inliers(pts, line, o.inlier_radius_mm), o.max_gap_mm);
  if (in.size() < static_cast<std::size_t>(o.min_inliers)) return d;
  line = Refit(pts, in);
  double s0 = std::numeric_limits<double>::infinity(), s1 = -s0;
  std::vector<double> values;
  for (auto i : in) {
    s0 = std::min(s0, line.Parameter(pts.p_mm[i]));
    s1 = std::max(s1, line.Parameter(pts.p_mm[i]));
    values.push_back(pts.value[i]);
  }
  d.line_length_mm = s1 - s0;
  if (d.line_length_mm < o.min_line_length_mm) return d;
  const auto box = v.BoundingBoxMm();
  const Eigen::Vector3d p0 = line.point + s0 * line.direction,
                        p1 = line.point + s1 * line.direction;
  const bool tip_high =
      DistanceToBox(box, p0, -line.direction) <= DistanceToBox(box, p1, line.direction);
  d.axis = Line3{line.point, tip_high ? line.direction : Eigen::Vector3d(-line.direction)};
  d.tip_mm = tip_high ? p1 : p0;
  d.found = true;
  d.confidence = std::min(1.0, static_cast<double>(in.size()) / (4.0 * o.min_inliers)) *
                 std::min(1.0, d.line_length_mm / std::max(1e-9, 2.0 * o.min_line_length_mm));
  FindTarget(v, UpperMedian(values), o, d);
  return d;
}

}  // namespace echoservo::tracking
