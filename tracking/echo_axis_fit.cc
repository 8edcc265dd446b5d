#include "tracking/echo_axis_fit.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

namespace echoservo::tracking {
namespace {

struct Echo {
  Eigen::Vector3d p;  // relative to the fit origin
  double w;
};

// First echoes within `radius` of `line`, weighted by (value − background)².
std::vector<Echo> GatherEchoes(const imaging::Volume& v, const Line3& line, double radius, double bg,
                               double first_echo_mm, const Eigen::Vector3d& origin) {
  std::vector<Echo> out;
  const Eigen::Vector3i dims = v.dims();
  const Eigen::Vector3d sp = v.spacing_mm();
  const double step = sp.minCoeff();
  const int look_steps = first_echo_mm > 0 ? static_cast<int>(std::ceil(first_echo_mm / step)) : 0;
  const Eigen::Vector3d dx = v.direction().col(0) * sp.x();
  for (int k = 0; k < dims.z(); ++k)
    for (int j = 0; j < dims.y(); ++j) {
      const Eigen::Vector3d row0 = v.IndexToPhysical(Eigen::Vector3d(0, j, k));
      const Eigen::Vector3d r0 = row0 - line.point;
      // Distance² to the line is quadratic in i: the index range within `radius`.
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
        const Eigen::Vector3d p = row0 + i * dx;
        if (look_steps > 0) {
          // Comet tails and the far wall lie behind a brighter echo along the beam.
          const Eigen::Vector3d back = -step * BeamDirectionAt(v, p);
          bool behind = false;
          for (int q = 1; q <= look_steps && !behind; ++q) {
            const Eigen::Vector3d idx = v.PhysicalToIndex(p + q * back);
            const int qi = static_cast<int>(std::lround(idx.x())), qj = static_cast<int>(std::lround(idx.y())),
                      qk = static_cast<int>(std::lround(idx.z()));
            if (qi < 0 || qj < 0 || qk < 0 || qi >= dims.x() || qj >= dims.y() || qk >= dims.z()) break;
            if (qi == i && qj == j && qk == k) continue;
            behind = v.at(qi, qj, qk) > x;
          }
          if (behind) continue;
        }
        out.push_back({p - origin, (x - bg) * (x - bg)});
      }
    }
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
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(scatter);
  if (line) *line = Line3{c, es.eigenvectors().col(2).normalized()};
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
  if (!(fit_radius_mm > 0 && fit_radius_mm < 50)) bad("fit_radius_mm", "must be in (0, 50)");
  if (!(first_echo_mm >= 0 && first_echo_mm < 50)) bad("first_echo_mm", "must be in [0, 50)");
  if (!(sheath_diameter_mm >= 0 && sheath_diameter_mm <= 20)) bad("sheath_diameter_mm", "must be in [0, 20]");
  if (!(wire_diameter_mm >= 0 && wire_diameter_mm <= sheath_diameter_mm))
    bad("wire_diameter_mm", "must be in [0, sheath_diameter_mm]");
  if (!(min_sheath_span_mm >= 0 && std::isfinite(min_sheath_span_mm))) bad("min_sheath_span_mm", "must be finite, ≥ 0");
}

Eigen::Vector3d BeamDirectionAt(const imaging::Volume& v, const Eigen::Vector3d& p_mm) {
  const Eigen::Isometry3d probe_to_image = v.image_to_probe().inverse();
  const Eigen::Vector3d apex = probe_to_image.translation();
  const Eigen::Vector3d axis = probe_to_image.linear().col(2);
  const Eigen::Vector3d r = p_mm - apex;
  if (r.dot(axis) <= 1e-6 * r.norm() || r.norm() < 1e-9) return axis;
  return r.normalized();
}

std::optional<EchoAxisFit> FitEchoAxis(const imaging::Volume& v, const Line3& start, double bg,
                                       const EchoAxisFitOptions& o) {
  const Eigen::Vector3d origin = start.point;
  Line3 line{Eigen::Vector3d::Zero(), start.direction.normalized()};
  std::vector<Echo> echoes;
  for (double f : {1.0, 0.8, 0.6}) {
    echoes = GatherEchoes(v, Line3{line.point + origin, line.direction}, f * o.fit_radius_mm, bg,
                          o.first_echo_mm, origin);
    if (echoes.size() < 4) return std::nullopt;
    const auto l = WeightedTls(echoes);
    if (!l) return std::nullopt;
    line = *l;
  }
  EchoAxisFit fit;
  fit.echo_line = Line3{line.point + origin, line.direction};
  fit.echo_count = static_cast<int>(echoes.size());
  const double R = 0.5 * o.sheath_diameter_mm, rho = 0.5 * o.wire_diameter_mm;
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
        const Eigen::Vector3d b = BeamDirectionAt(v, echoes[i].p + origin);
        const Eigen::Vector3d bp = b - b.dot(d) * d;
        nrm[i] = bp.norm() > 1e-9 ? Eigen::Vector3d(bp.normalized()) : Eigen::Vector3d::Zero();
      }
      std::iota(order.begin(), order.end(), std::size_t{0});
      std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return s[a] < s[b]; });
      // prefix[k]: moments of the k echoes with the smallest s.
      std::vector<Moments> prefix(n + 1);
      for (std::size_t k = 0; k < n; ++k) {
        prefix[k + 1] = prefix[k];
        prefix[k + 1].Add(echoes[order[k]].p, nrm[order[k]], echoes[order[k]].w);
      }
      double best = std::numeric_limits<double>::infinity();
      std::size_t best_k = n;
      double best_side = 1;
      double last_s = -std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k <= n; ++k) {
        if (k > 0 && k < n && s[order[k]] < last_s + 0.25) continue;
        if (k < n) last_s = s[order[k]];
        const Moments lo = prefix[k], hi = prefix[n] - prefix[k];
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
          }
        }
      }
      double W = 0;
      Eigen::Vector3d m1 = Eigen::Vector3d::Zero();
      Eigen::Matrix3d m2 = Eigen::Matrix3d::Zero();
      {
        const Moments lo = prefix[best_k], hi = prefix[n] - prefix[best_k];
        const Moments& sheath = best_side > 0 ? lo : hi;
        const Moments& wire = best_side > 0 ? hi : lo;
        // The sheath alone gives the axis when it spans enough of the line: a metal wire's
        // echo is spread behind its near wall by reverberation inside it, so its echo locus
        // is not ρ from its axis; the wire then only places the tip (FindTip).
        const bool sheath_only = sheath.w > 0 && SpanMm(s, order, best_side > 0 ? 0 : best_k,
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
  return fit;
}

}  // namespace echoservo::tracking
