#include "tracking/tube_check.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "tracking/axis_profile.h"
#include "tracking/echo_axis_fit.h"
#include "tracking/radon_transform.h"

namespace echoservo::tracking {

void TubeCheckOptions::Validate() const {
  auto bad = [](const std::string& f) {
    throw std::invalid_argument("TubeCheckOptions: bad " + f);
  };
  if (!(core_radius_mm > 0 && core_radius_mm < ring_inner_mm))
    bad("core_radius_mm (must be in (0, ring_inner_mm))");
  if (!(ring_outer_mm > ring_inner_mm && ring_outer_mm < 100))
    bad("ring_outer_mm (must be in (ring_inner_mm, 100))");
  if (sectors < 4 || sectors > 64) bad("sectors (must be in [4, 64])");
  if (!(behind_half_angle_rad >= 0 && behind_half_angle_rad < std::numbers::pi / 2))
    bad("behind_half_angle_rad");
  if (!(step_mm > 0 && step_mm < 100)) bad("step_mm");
  if (!(ribbon_decay_ratio >= 0 && ribbon_decay_ratio <= 1)) bad("ribbon_decay_ratio");
}

namespace {

double Median(std::vector<double> x) {
  if (x.empty()) return 0.0;
  auto mid = x.begin() + static_cast<long>(x.size() / 2);
  std::nth_element(x.begin(), mid, x.end());
  return *mid;
}

// The direction around the core at c (36 directions ⟂ the axis) brightest at the ring, when
// its brightness decays away from the core (a reverberation ribbon); zero otherwise. Each
// radius's value is the max across ±0.5 mm of the direction (a ribbon is ~1 mm wide).
Eigen::Vector3d RibbonAt(const imaging::Volume& v, const Line3& axis, const Eigen::Vector3d& u,
                         const Eigen::Vector3d& w, const Eigen::Vector3d& c,
                         double dynamic_range_db, const TubeCheckOptions& o) {
  const imaging::VolumeSampler sample(v);
  auto amplitude = [&](double display) { return EchoAmplitude(display, dynamic_range_db); };
  auto sample0 = [&](const Eigen::Vector3d& p) {
    const double x = sample(p);
    return std::isnan(x) ? 0.0 : x;
  };
  constexpr int kDirections = 36;
  auto along = [&](const Eigen::Vector3d& dir, double r) {
    const Eigen::Vector3d t = dir.cross(axis.direction);
    if (std::isnan(sample(c + r * dir))) return std::numeric_limits<double>::quiet_NaN();
    double m = 0;
    for (double x : {-0.5, 0.0, 0.5}) m = std::max(m, sample0(c + r * dir + x * t));
    return amplitude(m);
  };
  // NaN when no sample lies inside the volume (the volume's edge is not a decay).
  auto median_over = [&](const Eigen::Vector3d& dir, double r0, double r1) {
    std::vector<double> a;
    for (double r = r0; r <= r1 + 1e-9; r += 0.5)
      if (const double x = along(dir, r); !std::isnan(x)) a.push_back(x);
    return a.size() * 2 > static_cast<std::size_t>((r1 - r0) / 0.5 + 1)
               ? Median(std::move(a))
               : std::numeric_limits<double>::quiet_NaN();
  };
  double best = -1;
  Eigen::Vector3d best_dir = Eigen::Vector3d::Zero();
  for (int k = 0; k < kDirections; ++k) {
    const double a = k * 2 * std::numbers::pi / kDirections;
    const Eigen::Vector3d dir = std::cos(a) * u + std::sin(a) * w;
    const double x = median_over(dir, o.ring_inner_mm, o.ring_outer_mm);
    if (!std::isnan(x) && x > best) {
      best = x;
      best_dir = dir;
    }
  }
  if (best <= 0) return Eigen::Vector3d::Zero();
  const double near = median_over(best_dir, 2.0, 4.5);
  const double far = median_over(best_dir, 6.0, 9.0);
  return far < o.ribbon_decay_ratio * near ? best_dir : Eigen::Vector3d::Zero();  // NaN: false
}

}  // namespace

std::optional<Eigen::Vector3d> RibbonDirection(const imaging::Volume& v, const Line3& axis,
                                               double s_from, double s_to, double dynamic_range_db,
                                               const TubeCheckOptions& o) {
  Eigen::Vector3d u, w;
  PlaneBasis(axis.direction, u, w);
  const int sections =
      s_to >= s_from ? static_cast<int>(std::floor((s_to - s_from) / o.step_mm)) + 1 : 0;
  std::vector<Eigen::Vector3d> dirs(static_cast<std::size_t>(std::max(0, sections)),
                                    Eigen::Vector3d::Zero());
  std::vector<char> inside(dirs.size(), 0);
  tbb::parallel_for(0, std::max(0, sections), [&](int i) {
    const Eigen::Vector3d c = axis.point + (s_from + i * o.step_mm) * axis.direction;
    if (std::isnan(v.Sample(c))) return;
    inside[static_cast<std::size_t>(i)] = 1;
    dirs[static_cast<std::size_t>(i)] = RibbonAt(v, axis, u, w, c, dynamic_range_db, o);
  });
  int n_inside = 0, n_ribbon = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    n_inside += inside[i];
    if (dirs[i].norm() > 0.5) {
      ++n_ribbon;
      sum += dirs[i];
    }
  }
  // Most sections show a ribbon, and the same one (the beam's projection changes little
  // along a catheter).
  if (n_inside == 0 || 2 * n_ribbon < n_inside || sum.norm() < 0.8 * n_ribbon) return std::nullopt;
  Eigen::Vector3d e = sum - sum.dot(axis.direction) * axis.direction;
  if (e.norm() < 1e-9) return std::nullopt;
  return Eigen::Vector3d(e.normalized());
}

double Tubularity(const imaging::Volume& v, const Line3& axis, double s_from, double s_to,
                  double dynamic_range_db, const TubeCheckOptions& o) {
  return Tubularity(v, axis, s_from, s_to, dynamic_range_db, o, BeamGeometry::FromVolume(v));
}

double Tubularity(const imaging::Volume& v, const Line3& axis, double s_from, double s_to,
                  double dynamic_range_db, const TubeCheckOptions& o, const BeamGeometry& given,
                  bool search_ribbon) {
  // Unknown beams: a ribbon that most cross-sections agree on stands for them (parallel beams
  // along it); none: no sector is skipped.
  BeamGeometry beams = given;
  if (!beams.known() && search_ribbon)
    if (const auto e = RibbonDirection(v, axis, s_from, s_to, dynamic_range_db, o))
      beams = BeamGeometry::Parallel(*e);
  Eigen::Vector3d u, w;
  PlaneBasis(axis.direction, u, w);
  const imaging::VolumeSampler sample(v);
  auto amplitude = [&](double display) { return EchoAmplitude(display, dynamic_range_db); };
  auto sample0 = [&](const Eigen::Vector3d& p) {
    const double x = sample(p);
    return std::isnan(x) ? 0.0 : x;
  };
  constexpr int kRadial = 3;
  constexpr double kArcStepMm = 0.25;
  // One section every step_mm, in parallel (TBB); a section outside the volume is NaN.
  const int sections =
      s_to >= s_from ? static_cast<int>(std::floor((s_to - s_from) / o.step_mm)) + 1 : 0;
  std::vector<double> value(static_cast<std::size_t>(std::max(0, sections)),
                            std::numeric_limits<double>::quiet_NaN());
  tbb::parallel_for(0, std::max(0, sections), [&](int i) {
    const double s = s_from + i * o.step_mm;
    const Eigen::Vector3d c = axis.point + s * axis.direction;
    const double centre = sample(c);
    if (std::isnan(centre)) return;
    Eigen::Vector3d behind = Eigen::Vector3d::Zero();
    if (beams.known()) {
      const Eigen::Vector3d b = beams.At(c);
      behind = b - b.dot(axis.direction) * axis.direction;
    }
    const bool has_behind = behind.norm() > 1e-6;
    if (has_behind) behind.normalize();
    double core = centre;
    for (int k = 0; k < 8; ++k) {
      const double a = k * std::numbers::pi / 4;
      for (double r : {0.5 * o.core_radius_mm, o.core_radius_mm})
        core = std::max(core, sample0(c + r * (std::cos(a) * u + std::sin(a) * w)));
    }
    double surround = 0;
    for (int k = 0; k < o.sectors; ++k) {
      const double a = (k + 0.5) * 2 * std::numbers::pi / o.sectors;
      const Eigen::Vector3d dir = std::cos(a) * u + std::sin(a) * w;
      const Eigen::Vector3d tangent = -std::sin(a) * u + std::cos(a) * w;
      if (has_behind && std::acos(std::clamp(dir.dot(behind), -1.0, 1.0)) < o.behind_half_angle_rad)
        continue;
      // Per radius, the brightest sample across the sector's arc (a thin surface at any angle
      // within the sector registers); the sector's value is the median over radii (one
      // speckle spike does not make a sector bright).
      std::array<double, kRadial> at_r{};
      for (int q = 0; q < kRadial; ++q) {
        const double r = o.ring_inner_mm + (o.ring_outer_mm - o.ring_inner_mm) * q / (kRadial - 1);
        const double half_arc = r * std::tan(std::numbers::pi / o.sectors);
        double m = 0;
        for (double t = -half_arc; t <= half_arc + 1e-9; t += kArcStepMm)
          m = std::max(m, sample0(c + r * dir + t * tangent));
        at_r[static_cast<std::size_t>(q)] = m;
      }
      std::sort(at_r.begin(), at_r.end());
      surround = std::max(surround, at_r[kRadial / 2]);
    }
    value[static_cast<std::size_t>(i)] =
        std::clamp(1.0 - amplitude(surround) / amplitude(core), 0.0, 1.0);
  });
  std::vector<double> per_section;
  for (double x : value)
    if (!std::isnan(x)) per_section.push_back(x);
  if (per_section.empty()) return 0.0;
  auto mid = per_section.begin() + static_cast<long>(per_section.size() / 2);
  std::nth_element(per_section.begin(), mid, per_section.end());
  return *mid;
}

}  // namespace echoservo::tracking
