#include "tracking/echo_axis_fit.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "tracking/quadratic_range.h"

namespace echoservo::tracking {
namespace {

struct Echo {
  Eigen::Vector3d p;  // relative to the fit origin
  double w;
};

// A beam within 15° of the catheter's axis has no near wall to see (it runs along the tube),
// and looking back along it runs along the catheter itself: there the echoes are taken as
// they are (no first-echo rule, no near-wall offset).
constexpr double kMinBeamAxisSin = 0.2588;  // sin 15°

// The top of a log-compressed 8-bit display: a voxel there is clipped, at least this bright.
constexpr std::uint8_t kDisplayTop = 255;

// The sheath's far wall echoes a diameter behind its near wall along the beam; the first-echo
// look-back reaches this much further (the pulse's 3σ, ~0.9 mm, and the image's depth scale,
// assumed/true sound speed, up to ~+8 %).
constexpr double kFarWallMarginMm = 1.0;

// A voxel above the background near the search line; whether it is a first echo is decided
// when a pass first needs it (the test does not depend on the line).
struct Candidate {
  Eigen::Vector3d p;  // relative to the fit origin
  double w;           // (value − background)²
  std::int32_t i, j, k;
  std::uint8_t value;
  std::int8_t first_echo = -1;  // −1: not tested yet
};

// The first-echo rule: comet tails and the far wall lie behind a brighter echo along the
// beam, so a voxel with a brighter one up to `first_echo_mm` nearer the transducer is not
// one; nor is a clipped voxel (kDisplayTop) with a clipped one nearer: a saturated echo and
// its ring-down read as one run of equal values, whose first voxel is the echo's front.
// The look-back steps along the beam in index space.
class FirstEchoTest {
 public:
  FirstEchoTest(const imaging::Volume& v, double first_echo_mm, const BeamGeometry& beams,
                const Eigen::Vector3d& axis_direction)
      : v_(v),
        beams_(beams),
        axis_(axis_direction.normalized()),
        step_(v.spacing_mm().minCoeff()),
        look_steps_(first_echo_mm > 0 ? static_cast<int>(std::ceil(first_echo_mm / step_)) : 0),
        // Physical displacement → index displacement (Volume::PhysicalToIndex is affine).
        to_index_(Eigen::Matrix3d(v.direction() * v.spacing_mm().asDiagonal()).inverse()) {}

  bool operator()(const Candidate& c, const Eigen::Vector3d& origin) const {
    if (look_steps_ == 0) return true;
    const Eigen::Vector3d beam = beams_.At(c.p + origin);
    if (beam.cross(axis_).norm() < kMinBeamAxisSin) return true;
    const Eigen::Vector3i dims = v_.dims();
    const std::uint8_t* vox = v_.voxels().data();
    const std::ptrdiff_t sy = dims.x(), sz = static_cast<std::ptrdiff_t>(dims.x()) * dims.y();
    const Eigen::Vector3d back = to_index_ * (-step_ * beam);
    const Eigen::Vector3d idx = Eigen::Vector3d(c.i, c.j, c.k) + Eigen::Vector3d::Constant(0.5);
    for (int q = 1; q <= look_steps_; ++q) {
      // Rounding half away from zero (std::lround, a library call) of a coordinate x with
      // x + 0.5 > 0 is the truncation of x + 0.5; x ≤ −0.5 rounds below 0, out of the volume.
      const Eigen::Vector3d at = idx + q * back;
      if (at.x() <= 0 || at.y() <= 0 || at.z() <= 0) break;
      const long qi = static_cast<long>(at.x()), qj = static_cast<long>(at.y()),
                 qk = static_cast<long>(at.z());
      if (qi >= dims.x() || qj >= dims.y() || qk >= dims.z()) break;
      if (qi == c.i && qj == c.j && qk == c.k) continue;
      const std::uint8_t nearer = vox[qi + qj * sy + qk * sz];
      if (nearer > c.value || (nearer == kDisplayTop && c.value == kDisplayTop)) return false;
    }
    return true;
  }

 private:
  const imaging::Volume& v_;
  BeamGeometry beams_;
  Eigen::Vector3d axis_;  // the start line's direction (the catheter's, within degrees)
  double step_;
  int look_steps_;
  Eigen::Matrix3d to_index_;
};

// A voxel's position (mm, relative to `origin`) computed one way wherever it is needed, so
// that positions recomputed from indices equal those of the walk bit for bit.
struct VoxelGrid {
  explicit VoxelGrid(const imaging::Volume& v)
      : o(v.IndexToPhysical(Eigen::Vector3d::Zero())),
        dx(v.IndexToPhysical(Eigen::Vector3d::UnitX()) - o),
        dy(v.IndexToPhysical(Eigen::Vector3d::UnitY()) - o),
        dz(v.IndexToPhysical(Eigen::Vector3d::UnitZ()) - o) {}
  Eigen::Vector3d RowStart(int j, int k, const Eigen::Vector3d& origin) const {
    return o + j * dy + k * dz - origin;
  }
  Eigen::Vector3d InRow(const Eigen::Vector3d& row0, int i) const { return row0 + i * dx; }
  Eigen::Vector3d o, dx, dy, dz;
};

// Calls visit(k, i, j, x, p) for each voxel (i, j, k) of slice k, value x above `bg`, within
// `radius` of `line` and at most `max_along` along `along` (its position p relative to
// `origin`), in scan order (j, i) within the slice. The squared distance to the line is a
// quadratic in the voxel index: per slice, the rows that can come within `radius` are those
// where its minimum over i is small enough; per row, the i range solves it. Slices in
// parallel (TBB): a call writes only its own slice's results.
template <typename Visit>
void ForEachCylinderVoxel(const imaging::Volume& v, const Line3& line, double radius, double bg,
                          const Eigen::Vector3d& origin, const Eigen::Vector3d& along,
                          double max_along, Visit visit) {
  const Eigen::Vector3i dims = v.dims();
  const Eigen::Vector3d e = line.direction;
  auto perp = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d { return x - x.dot(e) * e; };
  const VoxelGrid grid(v);
  const Eigen::Vector3d &o = grid.o, &dx = grid.dx, &dy = grid.dy, &dz = grid.dz;
  const Eigen::Vector3d a = perp(dx), b = perp(dy);
  const double aa = a.squaredNorm(), ab = a.dot(b), bb = b.squaredNorm(), r2 = radius * radius;
  const bool bounded = std::isfinite(max_along);
  const std::uint8_t* vox = v.voxels().data();
  const std::ptrdiff_t sy = dims.x(), sz = static_cast<std::ptrdiff_t>(dims.x()) * dims.y();
  tbb::parallel_for(0, dims.z(), [&](int k) {
    // Squared distance of voxel (i, j, k): |c + i a + j b|².
    const Eigen::Vector3d c = perp(o + k * dz - line.point);
    const double ac = a.dot(c), bc = b.dot(c), cc = c.squaredNorm();
    int j0 = 0, j1 = 0;
    const bool rows = aa > 1e-12 ? QuadraticRange(bb - ab * ab / aa, bc - ac * ab / aa,
                                                  cc - ac * ac / aa - r2, dims.y(), j0, j1)
                                 : QuadraticRange(bb, bc, cc - r2, dims.y(), j0, j1);
    if (!rows) return;
    for (int j = j0; j <= j1; ++j) {
      // Along the row: d²(i) = cj·cj + 2 i a·cj + i² a·a, exactly tested per voxel.
      const double acj = ac + j * ab, ccj = cc + 2 * j * bc + static_cast<double>(j) * j * bb;
      int i0 = 0, i1 = 0;
      if (!QuadraticRange(aa, acj, ccj - r2, dims.x(), i0, i1)) continue;
      const Eigen::Vector3d row0 = grid.RowStart(j, k, origin);
      const std::uint8_t* row = vox + j * sy + k * sz;
      for (int i = i0; i <= i1; ++i) {
        const double x = row[i];
        if (x <= bg || ccj + i * (2 * acj + i * aa) > r2) continue;
        const Eigen::Vector3d p = grid.InRow(row0, i);
        if (bounded && p.dot(along) > max_along) continue;
        visit(k, i, j, row[i], p);
      }
    }
  });
}

// The voxels above `bg` within `radius` of `line` and at most `max_along` along `along`
// (ForEachCylinderVoxel), positions relative to `origin`, weight (value − bg)², in scan order
// (k, j, i). Slices concatenated in order: the result does not depend on the thread schedule.
std::vector<Candidate> GatherCandidates(const imaging::Volume& v, const Line3& line, double radius,
                                        double bg, const Eigen::Vector3d& origin,
                                        const Eigen::Vector3d& along, double max_along) {
  std::vector<std::vector<Candidate>> slices(static_cast<std::size_t>(v.dims().z()));
  ForEachCylinderVoxel(
      v, line, radius, bg, origin, along, max_along,
      [&](int k, int i, int j, std::uint8_t value, const Eigen::Vector3d& p) {
        const double x = value;
        slices[static_cast<std::size_t>(k)].push_back({p, (x - bg) * (x - bg), i, j, k, value});
      });
  std::size_t total = 0;
  for (const auto& c : slices) total += c.size();
  std::vector<Candidate> out;
  out.reserve(total);
  for (const auto& c : slices) out.insert(out.end(), c.begin(), c.end());
  return out;
}

// The catheter's echoes in a cylinder read for the first time, in one walk: the voxels above
// `bg` (ForEachCylinderVoxel) kept compactly (indices and value), the echo level their 99th
// percentile (the value at rank n·99/100 from 0, ascending, as std::nth_element picks it), the
// threshold `fraction` of the way from `bg` to it, and the Candidates built only for the voxels
// above it (positions recomputed from the indices by VoxelGrid, as the walk computes them;
// weight (value − threshold)²), in scan order (k, j, i). The speckle above the background is
// most of the cylinder: building its Candidates, or walking the cylinder twice, cost most of
// the fit. `threshold` is left unchanged when the cylinder holds no voxel above `bg`.
std::vector<Candidate> GatherAboveEchoLevel(const imaging::Volume& v, const Line3& line,
                                            double radius, double bg, double fraction,
                                            const Eigen::Vector3d& origin,
                                            const Eigen::Vector3d& along, double max_along,
                                            double& threshold) {
  struct Compact {
    int i, j;
    std::uint8_t value;
  };
  std::vector<std::vector<Compact>> slices(static_cast<std::size_t>(v.dims().z()));
  ForEachCylinderVoxel(v, line, radius, bg, origin, along, max_along,
                       [&](int k, int i, int j, std::uint8_t value, const Eigen::Vector3d&) {
                         slices[static_cast<std::size_t>(k)].push_back({i, j, value});
                       });
  std::array<std::uint64_t, 256> histogram{};
  std::uint64_t n = 0;
  for (const auto& slice : slices) {
    for (const Compact& c : slice) ++histogram[c.value];
    n += slice.size();
  }
  std::vector<Candidate> out;
  if (n == 0) return out;
  const std::uint64_t rank = n * 99 / 100;
  std::uint64_t below = 0;
  std::size_t level = 0;
  while (below + histogram[level] <= rank) below += histogram[level++];
  threshold = bg + fraction * (static_cast<double>(level) - bg);
  const VoxelGrid grid(v);
  for (std::size_t k = 0; k < slices.size(); ++k) {
    for (const Compact& c : slices[k]) {
      const double x = c.value;
      if (x <= threshold) continue;
      const Eigen::Vector3d p = grid.InRow(grid.RowStart(c.j, static_cast<int>(k), origin), c.i);
      out.push_back({p, (x - threshold) * (x - threshold), c.i, c.j, static_cast<int>(k), c.value});
    }
  }
  return out;
}

// Whether every point within `radius` of `inner` (in the volume) lies within `outer_radius`
// of `outer`: then a gather around `inner` is the outer gather's candidates near `inner`.
// A point x within r of inner, projecting onto it at q, is within r + d(q, outer) of outer;
// d(q, outer) along inner is the root of a convex quadratic, largest at an end of the
// volume's span along inner.
bool NestedCylinder(const imaging::Volume& v, const Line3& outer, double outer_radius,
                    const Line3& inner, double radius) {
  const Eigen::AlignedBox3d box = v.BoundingBoxMm();
  double s0 = std::numeric_limits<double>::infinity(), s1 = -s0;
  for (int c = 0; c < 8; ++c) {
    const double s = (box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)) - inner.point)
                         .dot(inner.direction);
    s0 = std::min(s0, s);
    s1 = std::max(s1, s);
  }
  const double slack = outer_radius - radius;
  return slack > 0 && PointToLineDistance(outer, inner.point + s0 * inner.direction) < slack &&
         PointToLineDistance(outer, inner.point + s1 * inner.direction) < slack;
}

// The candidates of `pool` (positions relative to the fit origin) within `radius` of
// `line` (relative too), in the same order.
std::vector<Candidate> WithinRadius(const std::vector<Candidate>& pool, const Line3& line,
                                    double radius) {
  std::vector<Candidate> out;
  out.reserve(pool.size());
  const double r2 = radius * radius;
  for (const auto& c : pool) {
    const Eigen::Vector3d r = c.p - line.point;
    const double t = r.dot(line.direction);
    if (r.squaredNorm() - t * t <= r2) out.push_back(c);
  }
  return out;
}

// Carries the first-echo answers of `before` (an earlier pass's candidates) over to the same
// voxels in `after`; both are in scan order, so one merge finds them.
void CarryFirstEchoAnswers(const std::vector<Candidate>& before, std::vector<Candidate>& after) {
  auto key = [](const Candidate& c) { return std::tuple(c.k, c.j, c.i); };
  std::size_t b = 0;
  for (auto& c : after) {
    while (b < before.size() && key(before[b]) < key(c)) ++b;
    if (b < before.size() && key(before[b]) == key(c)) c.first_echo = before[b].first_echo;
  }
}

// The first echoes among the candidates, in order. Candidates not tested yet are tested now
// (in parallel) and keep the answer.
std::vector<Echo> FirstEchoes(std::vector<Candidate>& pool, const FirstEchoTest& first_echo,
                              const Eigen::Vector3d& origin) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pool.size(), 512),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t n = r.begin(); n != r.end(); ++n)
                        if (pool[n].first_echo < 0)
                          pool[n].first_echo = first_echo(pool[n], origin) ? 1 : 0;
                    });
  std::vector<Echo> out;
  for (const auto& c : pool)
    if (c.first_echo > 0) out.push_back({c.p, c.w});
  return out;
}

std::optional<Line3> WeightedTls(const std::vector<Echo>& e) {
  std::vector<Eigen::Vector3d> pts;
  std::vector<double> wts;
  pts.reserve(e.size());
  wts.reserve(e.size());
  for (const auto& x : e) {
    pts.push_back(x.p);
    wts.push_back(x.w);
  }
  try {
    return FitLine(pts, wts);
  } catch (const std::invalid_argument&) {
    return std::nullopt;
  }
}

// Weighted first and second moments of points p + r·n, accumulated over a range.
struct Moments {
  double w = 0;
  Eigen::Vector3d sp = Eigen::Vector3d::Zero(), sn = Eigen::Vector3d::Zero();
  Eigen::Matrix3d spp = Eigen::Matrix3d::Zero(), spn = Eigen::Matrix3d::Zero(),
                  snn = Eigen::Matrix3d::Zero();
  void Add(const Eigen::Vector3d& p, const Eigen::Vector3d& n, double wt) {
    w += wt;
    sp += wt * p;
    sn += wt * n;
    spp.noalias() += wt * p * p.transpose();
    const Eigen::Matrix3d pn = wt * p * n.transpose();
    spn += pn + pn.transpose();
    snn.noalias() += wt * n * n.transpose();
  }
  Moments operator-(const Moments& o) const {
    Moments m;
    m.w = w - o.w;
    m.sp = sp - o.sp;
    m.sn = sn - o.sn;
    m.spp = spp - o.spp;
    m.spn = spn - o.spn;
    m.snn = snn - o.snn;
    return m;
  }
  // Σw, Σw q and Σw q qᵀ of q = p + r n.
  void Shifted(double r, double& W, Eigen::Vector3d& m1, Eigen::Matrix3d& m2) const {
    W += w;
    m1 += sp + r * sn;
    m2 += spp + r * spn + r * r * snn;
  }
};

// TLS line and its weighted residual Σ w d² from accumulated moments.
double TlsResidual(double W, const Eigen::Vector3d& m1, const Eigen::Matrix3d& m2, Line3* line) {
  const Eigen::Vector3d c = m1 / W;
  const Eigen::Matrix3d scatter = m2 - W * c * c.transpose();
  if (!line) {
    // The residual alone (the breakpoint search: hundreds of calls per fit) is the trace less
    // the largest eigenvalue, which the closed-form 3 × 3 solution gives accurately, ~6× faster
    // than the iterative solver (the small eigenvalues, which it gives less accurately when
    // nearly equal, are not needed).
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(scatter, Eigen::EigenvaluesOnly);
    return std::max(0.0, scatter.trace() - es.eigenvalues()(2));
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(scatter);
  *line = Line3{c, es.eigenvectors().col(2).normalized()};
  return std::max(0.0, es.eigenvalues()(0) + es.eigenvalues()(1));
}

// Extent (max − min of s) of the sorted echoes order[a, b).
double SpanMm(const std::vector<double>& s, const std::vector<std::size_t>& order, std::size_t a,
              std::size_t b) {
  if (b <= a) return 0.0;
  return s[order[b - 1]] - s[order[a]];
}

}  // namespace

void EchoAxisFitOptions::Validate() const {
  auto bad = [](const std::string& f, const std::string& why) {
    throw std::invalid_argument("EchoAxisFitOptions: " + f + " " + why);
  };
  params::kFitRadiusMm.Check(fit_radius_mm, "EchoAxisFitOptions");
  params::kFirstEchoMm.Check(first_echo_mm, "EchoAxisFitOptions");
  params::kSheathDiameterMm.Check(sheath_diameter_mm, "EchoAxisFitOptions");
  params::kWireDiameterMm.Check(wire_diameter_mm, "EchoAxisFitOptions");
  // What the near-wall model can describe: a guidewire inside the sheath's lumen (thinner
  // than the sheath; none modelled without a sheath), and a sheath whose wall's echoes lie
  // within the fit's cylinder (radius ≤ fit_radius_mm around the echoes' line).
  if (sheath_diameter_mm > 0 && !(wire_diameter_mm < sheath_diameter_mm))
    bad("wire_diameter_mm", "= " + formats::FormatParameterValue(wire_diameter_mm) +
                                " must be below sheath_diameter_mm = " +
                                formats::FormatParameterValue(sheath_diameter_mm) +
                                " (the guidewire runs in the sheath's lumen)");
  if (sheath_diameter_mm == 0 && wire_diameter_mm != 0)
    bad("wire_diameter_mm", "must be 0 when sheath_diameter_mm is 0 (no near-wall model)");
  if (!(sheath_diameter_mm <= 2 * fit_radius_mm))
    bad("sheath_diameter_mm",
        "= " + formats::FormatParameterValue(sheath_diameter_mm) +
            " is wider than 2 × fit_radius_mm = " +
            formats::FormatParameterValue(2 * fit_radius_mm) +
            ": the fit gathers the wall's echoes within fit_radius_mm of their line (raise "
            "fit_radius_mm for a wider sheath)");
  if (!(min_sheath_span_mm >= 0 && std::isfinite(min_sheath_span_mm)))
    bad("min_sheath_span_mm", "must be finite, ≥ 0");
  if (!(echo_level_fraction >= 0 && echo_level_fraction < 1))
    bad("echo_level_fraction", "must be in [0, 1)");
}

BeamGeometry BeamGeometry::FromVolume(const imaging::Volume& v) {
  if (!v.has_image_to_probe()) return {};
  const Eigen::Isometry3d probe_to_image = v.image_to_probe().inverse();
  BeamGeometry b;
  b.kind = Kind::kApex;
  b.apex_mm = probe_to_image.translation();
  b.axis = probe_to_image.linear().col(2);
  return b;
}

BeamGeometry BeamGeometry::FromApex(const Eigen::Vector3d& apex_mm) {
  if (!apex_mm.allFinite())
    throw std::invalid_argument("BeamGeometry::FromApex: the probe apex must be finite");
  BeamGeometry b;
  b.kind = Kind::kApex;
  b.apex_mm = apex_mm;
  return b;
}

BeamGeometry BeamGeometry::Parallel(const Eigen::Vector3d& direction) {
  if (!direction.allFinite() || !(direction.norm() > 1e-9))
    throw std::invalid_argument(
        "BeamGeometry::Parallel: the beam direction must be finite and non-zero");
  BeamGeometry b;
  b.kind = Kind::kParallel;
  b.axis = direction.normalized();
  return b;
}

Eigen::Vector3d BeamGeometry::At(const Eigen::Vector3d& p) const {
  switch (kind) {
    case Kind::kUnknown:
      return Eigen::Vector3d::Zero();
    case Kind::kParallel:
      return axis;
    case Kind::kApex:
      break;
  }
  const Eigen::Vector3d r = p - apex_mm;
  if (r.norm() < 1e-9) return axis.norm() > 0 ? axis : Eigen::Vector3d::UnitZ();
  if (axis.norm() > 0 && r.dot(axis) <= 1e-6 * r.norm()) return axis;
  return r.normalized();
}

Eigen::Vector3d BeamDirectionAt(const imaging::Volume& v, const Eigen::Vector3d& p_mm) {
  // The volume's transform, known or not (the identity: beams from the image origin).
  const Eigen::Isometry3d probe_to_image = v.image_to_probe().inverse();
  BeamGeometry b;
  b.kind = BeamGeometry::Kind::kApex;
  b.apex_mm = probe_to_image.translation();
  b.axis = probe_to_image.linear().col(2);
  return b.At(p_mm);
}

std::optional<EchoAxisFit> FitEchoAxis(const imaging::Volume& v, const Line3& start, double bg,
                                       const EchoAxisFitOptions& o) {
  return FitEchoAxis(v, start, bg, o, BeamGeometry::FromVolume(v));
}

std::optional<EchoAxisFit> FitEchoAxis(const imaging::Volume& v, const Line3& start, double bg,
                                       const EchoAxisFitOptions& o, const BeamGeometry& beams,
                                       double max_along_mm) {
  const Eigen::Vector3d along = start.direction.normalized();
  const Eigen::Vector3d origin = start.point;
  Line3 line{Eigen::Vector3d::Zero(), start.direction.normalized()};
  std::vector<Echo> echoes;
  // Each pass gathers the voxels of its cylinder; a voxel's first-echo test (which does not
  // depend on the line) runs once, when a pass first meets the voxel.
  // Unknown beams: no first-echo rule and no near-wall offset (the symmetric centre-line fit).
  // The look-back reaches past the sheath's far wall, a diameter behind its near wall.
  const double look_back_mm =
      o.first_echo_mm > 0 ? std::max(o.first_echo_mm, o.sheath_diameter_mm + kFarWallMarginMm)
                          : 0.0;
  const FirstEchoTest first_echo(v, beams.known() ? look_back_mm : 0.0, beams, start.direction);
  std::vector<Candidate> pool;
  Line3 pool_line = line;  // the cylinder `pool` was gathered in (relative to the origin)
  double pool_radius = 0, threshold = bg;
  for (double f : {1.0, 0.8, 0.6}) {
    const double radius = f * o.fit_radius_mm;
    // A narrower cylinder within the last gathered one is a subset of its candidates (same
    // threshold, first-echo answers kept); otherwise the volume is read again.
    if (!pool.empty() && NestedCylinder(v, pool_line, pool_radius, line, radius)) {
      pool = WithinRadius(pool, line, radius);
    } else {
      const Line3 cylinder{line.point + origin, line.direction};
      // The catheter's echo level: the 99th percentile of the cylinder's voxels above the
      // background (the catheter fills a few per cent of it; speckle the rest). Only voxels
      // above `echo_level_fraction` of the way to it are echoes of the catheter.
      std::vector<Candidate> next =
          pool.empty() && o.echo_level_fraction > 0
              ? GatherAboveEchoLevel(v, cylinder, radius, threshold, o.echo_level_fraction, origin,
                                     along, max_along_mm, threshold)
              : GatherCandidates(v, cylinder, radius, threshold, origin, along, max_along_mm);
      pool_line = line;
      pool_radius = radius;
      CarryFirstEchoAnswers(pool, next);
      pool = std::move(next);
    }
    echoes = FirstEchoes(pool, first_echo, origin);
    if (echoes.size() < 4) return std::nullopt;
    const auto l = WeightedTls(echoes);
    if (!l) return std::nullopt;
    line = *l;
  }
  EchoAxisFit fit;
  fit.echo_line = Line3{line.point + origin, line.direction};
  fit.echo_count = static_cast<int>(echoes.size());
  const double R = beams.known() ? 0.5 * o.sheath_diameter_mm : 0.0,
               rho = beams.known() ? 0.5 * o.wire_diameter_mm : 0.0;
  Line3 axis = line;
  if (R > 0) {
    const std::size_t n = echoes.size();
    std::vector<std::size_t> order(n);
    std::vector<double> s(n);
    std::vector<Eigen::Vector3d> nrm(n);
    for (int iter = 0; iter < 3; ++iter) {
      const Eigen::Vector3d d = axis.direction;
      for (std::size_t i = 0; i < n; ++i) {
        s[i] = (echoes[i].p - axis.point).dot(d);
        const Eigen::Vector3d b = beams.At(echoes[i].p + origin);
        const Eigen::Vector3d bp = b - b.dot(d) * d;
        nrm[i] = bp.norm() >= kMinBeamAxisSin ? Eigen::Vector3d(bp.normalized())
                                              : Eigen::Vector3d::Zero();
      }
      std::iota(order.begin(), order.end(), std::size_t{0});
      std::sort(order.begin(), order.end(),
                [&](std::size_t a, std::size_t b) { return s[a] < s[b]; });
      // `lo`: running moments of the k echoes with the smallest s (the same sums, in the same
      // order, as a table of prefix moments, without storing one per echo); `hi` the rest.
      Moments total;
      for (std::size_t k = 0; k < n; ++k)
        total.Add(echoes[order[k]].p, nrm[order[k]], echoes[order[k]].w);
      Moments lo, best_lo = total;
      double best = std::numeric_limits<double>::infinity();
      std::size_t best_k = n;
      double best_side = 1;
      double last_s = -std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k <= n; ++k) {
        if (k > 0) lo.Add(echoes[order[k - 1]].p, nrm[order[k - 1]], echoes[order[k - 1]].w);
        if (k > 0 && k < n && s[order[k]] < last_s + 0.25) continue;
        if (k < n) last_s = s[order[k]];
        const Moments hi = total - lo;
        for (double side : {1.0, -1.0}) {
          // side +1: sheath at s below the breakpoint, wire above; −1: the reverse.
          double W = 0;
          Eigen::Vector3d m1 = Eigen::Vector3d::Zero();
          Eigen::Matrix3d m2 = Eigen::Matrix3d::Zero();
          lo.Shifted(side > 0 ? R : rho, W, m1, m2);
          hi.Shifted(side > 0 ? rho : R, W, m1, m2);
          if (!(W > 0)) continue;
          const double res = TlsResidual(W, m1, m2, nullptr);
          if (res < best) {
            best = res;
            best_k = k;
            best_side = side;
            best_lo = lo;
          }
        }
      }
      double W = 0;
      Eigen::Vector3d m1 = Eigen::Vector3d::Zero();
      Eigen::Matrix3d m2 = Eigen::Matrix3d::Zero();
      {
        const Moments hi = total - best_lo;
        const Moments& sheath = best_side > 0 ? best_lo : hi;
        const Moments& wire = best_side > 0 ? hi : best_lo;
        // The sheath alone gives the axis when it spans enough of the line: a metal wire's
        // echo is spread behind its near wall by reverberation inside it, so its echo locus
        // is not ρ from its axis; the wire then only places the tip (FindTip).
        const bool sheath_only =
            sheath.w > 0 && SpanMm(s, order, best_side > 0 ? 0 : best_k,
                                   best_side > 0 ? best_k : n) >= o.min_sheath_span_mm;
        sheath.Shifted(R, W, m1, m2);
        if (!sheath_only) wire.Shifted(rho, W, m1, m2);
      }
      Line3 next;
      const double res = TlsResidual(W, m1, m2, &next);
      if (next.direction.dot(axis.direction) < 0) next.direction = -next.direction;
      const bool interior = best_k > 0 && best_k < n;
      const double sb = interior ? 0.5 * (s[order[best_k - 1]] + s[order[best_k]]) : 0.0;
      const Eigen::Vector3d breakpoint = axis.point + sb * axis.direction;
      axis = next;
      fit.rms_mm = std::sqrt(res / W);
      fit.wire_found = interior && R > rho;
      fit.sheath_end_s = (breakpoint - axis.point).dot(axis.direction);
      fit.wire_direction = best_side;
    }
  }
  fit.axis = Line3{axis.point + origin, axis.direction};
  fit.echo_s_min = std::numeric_limits<double>::infinity();
  fit.echo_s_max = -fit.echo_s_min;
  for (const auto& e : echoes) {
    const double s = fit.axis.Parameter(e.p + origin);
    fit.echo_s_min = std::min(fit.echo_s_min, s);
    fit.echo_s_max = std::max(fit.echo_s_max, s);
  }
  return fit;
}

}  // namespace echoservo::tracking
