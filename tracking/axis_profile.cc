#include "tracking/axis_profile.h"

#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <optional>
#include <vector>

#include "tracking/echo_axis_fit.h"
#include "tracking/radon_transform.h"

namespace echoservo::tracking {
namespace {

using Sampler = imaging::VolumeSampler;

// A trilinear sample this high lies among clipped voxels (the 8-bit display's top, 255).
constexpr double kClippedDisplay = 254.5;

// Max (or mean) of the samples over a small disc ⟂ the axis (the centre and 8 points at
// radius r, offsets computed once) at s. The max keeps a thin bright line bright under a
// sub-voxel axis error; the mean averages speckle over a broad surface.
class DiscProfile {
 public:
  enum class Reduce { kMax, kMean };
  DiscProfile(const imaging::Volume& v, const Line3& l, const Eigen::Vector3d& u,
              const Eigen::Vector3d& w, double r, Reduce reduce = Reduce::kMax)
      : sample_(v), line_(l), reduce_(reduce) {
    for (int k = 0; k < 8; ++k) {
      const double a = k * std::numbers::pi / 4;
      offsets_[static_cast<std::size_t>(k)] = r * (std::cos(a) * u + std::sin(a) * w);
    }
  }

  double operator()(double s) const {
    const Eigen::Vector3d c = line_.point + s * line_.direction;
    double m = sample_(c);
    if (std::isnan(m)) return m;
    double sum = m;
    int n = 1;
    for (const auto& o : offsets_) {
      const double x = sample_(c + o);
      if (std::isnan(x)) continue;
      m = std::max(m, x);
      sum += x;
      ++n;
    }
    return reduce_ == Reduce::kMax ? m : sum / n;
  }

 private:
  Sampler sample_;
  Line3 line_;
  Reduce reduce_;
  std::array<Eigen::Vector3d, 8> offsets_;
};

// The max of the disc's first echoes at s (DiscProfile's disc): a sample counts when no sample
// up to `look_back_mm` nearer the transducer along its beam (tracking/echo_axis_fit.h
// BeamDirectionAt) is brighter, nor clipped when it is clipped (the display's top: a
// saturated echo and its ring-down are one run of equal values). With none, the disc's
// smallest sample (all tails: not the wire's echo).
class FirstEchoDiscProfile {
 public:
  FirstEchoDiscProfile(const imaging::Volume& v, const Line3& l, const Eigen::Vector3d& u,
                       const Eigen::Vector3d& w, double r, double look_back_mm)
      : volume_(v),
        sample_(v),
        line_(l),
        step_(0.5 * v.spacing_mm().minCoeff()),
        steps_(static_cast<int>(std::ceil(look_back_mm / step_))) {
    offsets_[0] = Eigen::Vector3d::Zero();
    for (int k = 0; k < 8; ++k) {
      const double a = k * std::numbers::pi / 4;
      offsets_[static_cast<std::size_t>(k + 1)] = r * (std::cos(a) * u + std::sin(a) * w);
    }
  }

  double operator()(double s) const {
    const Eigen::Vector3d c = line_.point + s * line_.direction;
    double best = std::numeric_limits<double>::quiet_NaN(), least = best;
    for (const auto& o : offsets_) {
      const Eigen::Vector3d p = c + o;
      const double x = sample_(p);
      if (std::isnan(x)) continue;
      if (!(least <= x)) least = x;
      const Eigen::Vector3d back = -step_ * BeamDirectionAt(volume_, p);
      bool first = true;
      for (int q = 1; q <= steps_ && first; ++q) {
        const double y = sample_(p + q * back);
        if (std::isnan(y)) break;
        first = !(y > x || (y >= kClippedDisplay && x >= kClippedDisplay));
      }
      if (first && !(best >= x)) best = x;
    }
    return std::isnan(best) ? least : best;
  }

 private:
  const imaging::Volume& volume_;
  Sampler sample_;
  Line3 line_;
  double step_;
  int steps_;
  std::array<Eigen::Vector3d, 9> offsets_;
};

// The Gaussian envelope g(z) = exp(−z²/2) and its integral Φ(z), tabulated on z ∈ [−6, 6]
// (linear interpolation, error < 1e-4): the surface fit below evaluates them ~10^4 times.
class GaussianTables {
 public:
  GaussianTables() {
    for (int i = 0; i < kSize; ++i) {
      const double z = -kRange + i / kPerUnit;
      g_[static_cast<std::size_t>(i)] = std::exp(-0.5 * z * z);
      phi_[static_cast<std::size_t>(i)] = 0.5 * std::erfc(-z / std::numbers::sqrt2);
    }
  }
  void operator()(double z, double& g, double& phi) const {
    const double x = std::clamp((z + kRange) * kPerUnit, 0.0, kSize - 1.000001);
    const int i = static_cast<int>(x);
    const double f = x - i;
    const auto k = static_cast<std::size_t>(i);
    g = g_[k] + f * (g_[k + 1] - g_[k]);
    phi = phi_[k] + f * (phi_[k + 1] - phi_[k]);
  }

 private:
  static constexpr double kRange = 6.0, kPerUnit = 64.0;
  static constexpr int kSize = static_cast<int>(2 * kRange * kPerUnit) + 1;
  std::array<double, kSize> g_{}, phi_{};
};

// Squared residual of the best non-negative fit b + h·g + c·Φ (b free, h, c ≥ 0) to `amp`
// for one surface position s0 (samples) and blur σ (samples); b, h, c in closed form for
// each subset of the non-negative terms.
// `terms(k, g, phi)` gives sample k's envelope g and its integral Φ.
template <typename Terms>
double SurfaceFitResidualOf(const std::vector<double>& amp, const Terms& terms) {
  // Normal equations of the rows (1, g_k, Φ_k), summed as scalars.
  double sg = 0, sp = 0, sgg = 0, sgp = 0, spp = 0, sa = 0, sag = 0, sap = 0, btb = 0;
  for (std::size_t k = 0; k < amp.size(); ++k) {
    double g, phi;
    terms(k, g, phi);
    const double a = amp[k];
    sg += g;
    sp += phi;
    sgg += g * g;
    sgp += g * phi;
    spp += phi * phi;
    sa += a;
    sag += a * g;
    sap += a * phi;
    btb += a * a;
  }
  // The normal equations solved in closed form (3 × 3 by cofactors, the 2 × 2 subsets by
  // Cramer's rule): the grid search below solves them ~10^3 times per profile.
  const double n = static_cast<double>(amp.size());
  auto residual = [&](double b, double h, double c) {
    // |a − (b + h g + c Φ)|² expanded with the sums above.
    return btb - 2.0 * (b * sa + h * sag + c * sap) +
           (b * b * n + h * h * sgg + c * c * spp + 2.0 * (b * h * sg + b * c * sp + h * c * sgp));
  };
  // Both terms first: when feasible, no subset fits better.
  {
    const double c00 = sgg * spp - sgp * sgp, c01 = sp * sgp - sg * spp, c02 = sg * sgp - sp * sgg;
    const double det = n * c00 + sg * c01 + sp * c02;
    if (std::abs(det) > 1e-300) {
      const double c11 = n * spp - sp * sp, c12 = sg * sp - n * sgp, c22 = n * sgg - sg * sg;
      const double b = (c00 * sa + c01 * sag + c02 * sap) / det;
      const double h = (c01 * sa + c11 * sag + c12 * sap) / det;
      const double c = (c02 * sa + c12 * sag + c22 * sap) / det;
      if (h >= 0.0 && c >= 0.0) return residual(b, h, c);
    }
  }
  double best = std::numeric_limits<double>::infinity();
  // One term (x = g or Φ with sums sx, sxx, sax): [n sx; sx sxx] (b, k) = (sa, sax).
  auto one = [&](double sx, double sxx, double sax, bool echo) {
    const double det = n * sxx - sx * sx;
    if (!(std::abs(det) > 1e-300)) return;
    const double b = (sxx * sa - sx * sax) / det, k = (n * sax - sx * sa) / det;
    if (k < 0.0) return;
    best = std::min(best, echo ? residual(b, k, 0.0) : residual(b, 0.0, k));
  };
  one(sg, sgg, sag, true);
  one(sp, spp, sap, false);
  return best;
}

const GaussianTables& Tables() {
  static const GaussianTables tables;
  return tables;
}

double SurfaceFitResidual(const std::vector<double>& amp, double s0, double sigma) {
  const GaussianTables& tables = Tables();
  return SurfaceFitResidualOf(amp, [&](std::size_t k, double& g, double& phi) {
    tables((static_cast<double>(k) - s0) / sigma, g, phi);
  });
}

// The residuals of one σ at s0 = i·step, i = 0 … count − 1, when 1/step is an integer q
// (ds = 0.25 mm: step 0.5 sample): k − s0 = (q·k − i)·step exactly, so the envelope's values
// are tabulated once per lattice offset and read by every s0 — the same numbers
// SurfaceFitResidual computes, at a fraction of the table look-ups.
void LatticeResiduals(const std::vector<double>& amp, double step, int q, int count, double sigma,
                      std::vector<double>& g_at, std::vector<double>& phi_at,
                      std::vector<double>& out) {
  const GaussianTables& tables = Tables();
  const int n = static_cast<int>(amp.size());
  const int lo = -(count - 1), hi = q * (n - 1);  // q·k − i over k < n, i < count
  g_at.resize(static_cast<std::size_t>(hi - lo + 1));
  phi_at.resize(g_at.size());
  for (int m = lo; m <= hi; ++m)
    tables(static_cast<double>(m) * step / sigma, g_at[static_cast<std::size_t>(m - lo)],
           phi_at[static_cast<std::size_t>(m - lo)]);
  out.resize(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i)
    out[static_cast<std::size_t>(i)] =
        SurfaceFitResidualOf(amp, [&](std::size_t k, double& g, double& phi) {
          const auto at = static_cast<std::size_t>(q * static_cast<int>(k) - i - lo);
          g = g_at[at];
          phi = phi_at[at];
        });
}

// Surface position (in samples of `amp`) from an amplitude profile across a tissue surface:
// the least-squares fit of b + h·g((s − s0)/σ) + c·Φ((s − s0)/σ) — background, the
// interface's echo (the pulse envelope g) and the tissue's backscatter from the surface on
// (Φ, the envelope's integral) — over s0 and σ ∈ [0.15, 1.0] mm: a 0.125 mm × 0.1 mm grid,
// then a 0.0125 mm × 0.025 mm grid around its best.
double FitSurfaceEcho(const std::vector<double>& amp, double ds) {
  const double n = static_cast<double>(amp.size());
  double best_err = std::numeric_limits<double>::infinity(), best_s0 = 0.0, best_sigma_mm = 0.3;
  auto search = [&](double s0_lo, double s0_hi, double s0_step, double sg_lo, double sg_hi,
                    double sg_step) {
    for (double sigma_mm = sg_lo; sigma_mm <= sg_hi + 1e-9; sigma_mm += sg_step)
      for (double s0 = s0_lo; s0 <= s0_hi + 1e-9; s0 += s0_step) {
        const double err = SurfaceFitResidual(amp, s0, sigma_mm / ds);
        if (err < best_err) {
          best_err = err;
          best_s0 = s0;
          best_sigma_mm = sigma_mm;
        }
      }
  };
  const double step = 0.125 / ds;
  const double q = 1.0 / step;
  if (q == std::floor(q) && q >= 1 && q <= 64) {
    // The coarse grid on the lattice s0 = i·step (the same s0, σ and order as `search`).
    std::vector<double> g_at, phi_at, err;
    int count = 0;
    for (double s0 = 0.0; s0 <= n - 1 + 1e-9; s0 += step) ++count;
    for (double sigma_mm = 0.15; sigma_mm <= 1.0 + 1e-9; sigma_mm += 0.1) {
      LatticeResiduals(amp, step, static_cast<int>(q), count, sigma_mm / ds, g_at, phi_at, err);
      double s0 = 0.0;
      for (int i = 0; i < count; ++i, s0 += step)
        if (err[static_cast<std::size_t>(i)] < best_err) {
          best_err = err[static_cast<std::size_t>(i)];
          best_s0 = s0;
          best_sigma_mm = sigma_mm;
        }
    }
  } else {
    search(0.0, n - 1, step, 0.15, 1.0, 0.1);
  }
  const double s0 = best_s0, sg = best_sigma_mm;
  search(std::max(0.0, s0 - 0.125 / ds), std::min(n - 1, s0 + 0.125 / ds), 0.0125 / ds,
         std::max(0.1, sg - 0.1), sg + 0.1, 0.025);
  return best_s0;
}

}  // namespace

double EchoAmplitude(double display, double dynamic_range_db) {
  return std::pow(10.0, display / 255.0 * dynamic_range_db / 20.0);
}

TipEstimate FindTip(const imaging::Volume& v, const Line3& axis, double bg,
                    const EdgeOptions& edge) {
  const double tip_fraction = edge.edge_fraction;
  auto A = [&](double x) { return EchoAmplitude(x, edge.dynamic_range_db); };
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
  const DiscProfile profile(v, line, u, w, 0.6);
  for (double s = s_c - ext; s <= s_c + ext; s += ds) {
    s_val.push_back(s);
    prof.push_back(profile(s));
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
    if (n > 0 && !std::isnan(prof[static_cast<std::size_t>(i)]) &&
        prof[static_cast<std::size_t>(i)] > 0)
      sm[static_cast<std::size_t>(i)] = sum / n;
  }
  std::vector<double> valid;
  for (double x : sm)
    if (!std::isnan(x)) valid.push_back(x);
  if (valid.size() < 8) return out;
  std::sort(valid.begin(), valid.end());
  const double p90 = valid[valid.size() * 9 / 10];
  if (p90 <= bg + 10) return out;
  const double thr = bg + 0.3 * (p90 - bg);
  // The run above thr (2 mm gaps allowed) with the most echo above thr: the wire echoes 20–40
  // dB above tissue, so a long run of tissue (the axis inside the tissue beyond the tip, or
  // along a wall) does not outweigh the catheter, where the longest run would take it.
  int best_a = -1, best_b = -1, a = -1, last = -1;
  double run_sum = 0.0, best_sum = -1.0;
  const int gap = static_cast<int>(2.0 / ds);
  for (int i = 0; i < N; ++i) {
    const double x = sm[static_cast<std::size_t>(i)];
    if (!std::isnan(x) && x >= thr) {
      if (a < 0 || i - last > gap) {
        a = i;
        run_sum = 0.0;
      }
      last = i;
      run_sum += x - thr;
      if (run_sum > best_sum) {
        best_sum = run_sum;
        best_a = a;
        best_b = last;
      }
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
    if (!std::isnan(sm[static_cast<std::size_t>(q)]))
      loc.push_back(sm[static_cast<std::size_t>(q)]);
  }
  std::sort(loc.begin(), loc.end());
  const double level = loc.empty() ? p90 : loc[loc.size() / 2];
  const double cut = A(bg) + tip_fraction * (A(level) - A(bg));
  double tip_s = s_val[static_cast<std::size_t>(tip_i)];
  {
    // From inside the run (3 mm back from its end), outward to the first sample below cut.
    int q = tip_i;
    for (int t = 0; t < static_cast<int>(3.0 / ds) && q - step >= best_a && q - step <= best_b; ++t)
      q -= step;
    while (q + step >= 0 && q + step < N && !std::isnan(sm[static_cast<std::size_t>(q + step)]) &&
           A(prof[static_cast<std::size_t>(q + step)]) >= cut)
      q += step;
    const int r = q + step;
    tip_s = s_val[static_cast<std::size_t>(q)];
    if (r >= 0 && r < N && !std::isnan(prof[static_cast<std::size_t>(r)])) {
      const double x0 = A(prof[static_cast<std::size_t>(q)]),
                   x1 = A(prof[static_cast<std::size_t>(r)]);
      if (x0 > x1) tip_s += step * ds * std::clamp((x0 - cut) / (x0 - x1), 0.0, 1.0);
    }
  }
  if (edge.tip_first_echo_mm > 0) {
    // The same edge on first echoes only, within 3 mm of it: the level over the 3 mm inside
    // it (1 mm box smoothed, median) and the outward crossing of its cut.
    const FirstEchoDiscProfile first(v, line, u, w, 0.6, edge.tip_first_echo_mm);
    const int half = static_cast<int>(3.0 / ds);
    std::vector<double> fs_val, fe;
    for (int t = -half; t <= half; ++t) {
      fs_val.push_back(tip_s + step * t * ds);
      fe.push_back(first(fs_val.back()));
    }
    std::vector<double> inside;
    for (int i = 2; i < half; ++i) {
      double sum = 0;
      int n = 0;
      for (int t = -2; t <= 2; ++t)
        if (!std::isnan(fe[static_cast<std::size_t>(i + t)])) {
          sum += fe[static_cast<std::size_t>(i + t)];
          ++n;
        }
      if (n > 0) inside.push_back(sum / n);
    }
    if (inside.size() >= 4) {
      std::sort(inside.begin(), inside.end());
      const double fe_level = inside[inside.size() / 2];
      const double fe_cut = A(bg) + tip_fraction * (A(fe_level) - A(bg));
      int q = 0;
      while (q + 1 < static_cast<int>(fe.size()) &&
             !std::isnan(fe[static_cast<std::size_t>(q + 1)]) &&
             A(fe[static_cast<std::size_t>(q + 1)]) >= fe_cut)
        ++q;
      if (q > 0 && q + 1 < static_cast<int>(fe.size()) && fe_level > bg) {
        double s_edge = fs_val[static_cast<std::size_t>(q)];
        const double x0 = A(fe[static_cast<std::size_t>(q)]);
        const double x1 = A(fe[static_cast<std::size_t>(q + 1)]);
        if (!std::isnan(x1) && x0 > x1)
          s_edge += step * ds * std::clamp((x0 - fe_cut) / (x0 - x1), 0.0, 1.0);
        tip_s = s_edge;
      }
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

namespace {

// A profile's samples x(i·ds), i = 0, 1, …, computed on demand: up to `limit` samples, or
// to the first NaN (where the profile leaves the volume). A surface is usually found in the
// first centimetres of a profile that runs to the far side of the volume.
class LazyProfile {
 public:
  LazyProfile(const DiscProfile& profile, double ds, int limit)
      : profile_(profile), ds_(ds), limit_(limit) {}

  // The samples after computing the first n (fewer when the profile ends before).
  const std::vector<double>& Upto(int n) {
    n = std::min(n, limit_);
    while (!ended_ && static_cast<int>(x_.size()) < n) {
      const double x = profile_(static_cast<double>(x_.size()) * ds_);
      if (std::isnan(x)) {
        ended_ = true;
        break;
      }
      x_.push_back(x);
    }
    if (static_cast<int>(x_.size()) >= limit_) ended_ = true;
    return x_;
  }
  // Every sample is computed: the profile ended or reached `limit`.
  bool complete() const { return ended_; }

 private:
  const DiscProfile& profile_;
  double ds_;
  int limit_;
  std::vector<double> x_;
  bool ended_ = false;
};

// The number of samples s = 0, ds, 2·ds, … with s ≤ length_mm (s accumulated as a loop
// would: ds = 0.25 adds exactly).
int SampleCount(double length_mm, double ds) {
  int n = 0;
  for (double s = 0; s <= length_mm; s += ds) ++n;
  return n;
}

// FirstSurface (below) on the samples so far, `whole` when they are all the profile's:
// the result, or nothing when it may depend on samples not computed yet (a 3-sample mean at
// the last one, the background window or the fit window past the end, no rise yet).
std::optional<double> FirstSurfaceOn(const std::vector<double>& fp, bool whole, double ds, int from,
                                     int bg_lo, int bg_hi, double rise_floor,
                                     double dynamic_range_db) {
  const int M = static_cast<int>(fp.size());
  const double none = std::numeric_limits<double>::quiet_NaN();
  // The background window's 3-sample means are final when the sample after it is there.
  if (!whole && M <= bg_hi) return std::nullopt;
  // 0.75 mm box: shorter than the echo of an interface (a pulse's envelope), longer than
  // one speckle grain's sampling.
  std::vector<double> fs(static_cast<std::size_t>(M), 0);
  for (int i = 0; i < M; ++i) {
    double sum = 0;
    int n = 0;
    for (int t = -1; t <= 1; ++t)
      if (i + t >= 0 && i + t < M) {
        sum += fp[static_cast<std::size_t>(i + t)];
        ++n;
      }
    fs[static_cast<std::size_t>(i)] = sum / n;
  }
  auto at = [&](int i) { return fs[static_cast<std::size_t>(i)]; };
  double fbg = 0.0, spread = 0.0;
  {
    std::vector<double> near;
    for (int i = std::max(0, bg_lo); i < std::min(M, bg_hi); ++i) near.push_back(at(i));
    if (near.empty()) return none;  // an empty window (M > bg_hi when not whole)
    const MedianMad m = ComputeMedianMad(near);
    fbg = m.median;
    spread = 1.4826 * m.mad;
  }
  const double rise = std::max(rise_floor, 5.0 * spread);
  const int last = whole ? M - 1 : M - 2;  // the last sample whose mean is final
  for (int i = std::max(0, from); i <= last; ++i) {
    if (at(i) <= fbg + rise) continue;
    // The tissue surface images as the pulse envelope centred on it plus the tissue's own
    // backscatter from the surface on, both blurred by the point-spread function: fit that
    // model around the rise. The rise began where the profile last left the background (a
    // speckled surface can cross the threshold a little inside it).
    int onset = i;
    while (onset > from && at(onset - 1) > fbg + 0.5 * rise) --onset;
    const int reach = onset + static_cast<int>(2.5 / ds);
    if (!whole && reach > M - 1) return std::nullopt;
    std::vector<double> amp;
    const int i0 = std::max(0, onset - static_cast<int>(1.5 / ds)), i1 = std::min(M - 1, reach);
    for (int k = i0; k <= i1; ++k)
      amp.push_back(EchoAmplitude(fp[static_cast<std::size_t>(k)], dynamic_range_db));
    return i0 + FitSurfaceEcho(amp, ds);
  }
  return whole ? std::optional<double>(none) : std::nullopt;
}

// One surface position along a profile (samples `ds` apart, s = s_first + i·ds): the first
// rise above the background (median and robust spread of [bg_lo, bg_hi)) by
// max(12, 10 % of the line level above the volume's background, 5 × spread), walked back to
// where the profile last stood within half that rise, then located by FitSurfaceEcho over
// −1.5…+2.5 mm around that onset. Searched from index `from`; NaN when there is none. The
// profile is computed as far as the answer needs (the same answer as on all of it).
double FirstSurface(LazyProfile& profile, double ds, int from, int bg_lo, int bg_hi,
                    double rise_floor, double dynamic_range_db) {
  for (int n = std::max(from, bg_hi) + 64;; n *= 2) {
    const std::vector<double>& fp = profile.Upto(n);
    if (const auto r = FirstSurfaceOn(fp, profile.complete(), ds, from, bg_lo, bg_hi, rise_floor,
                                      dynamic_range_db))
      return *r;
  }
}

// The tissue surface beside the tip: rays parallel to the axis at lateral_radius_mm around
// it (8 directions, the one(s) behind the wire along the beam skipped: its comet tail and
// shadow), each searched from lateral_back_mm before the tip for its first surface; a plane
// s = a + b·x + c·y fitted to them (the worst ray beyond 1 mm dropped, repeatedly) and met
// with the axis at s = a. The surface extends sideways beyond the catheter's radius; the
// tip does not, so the tip's own echo does not enter these profiles.
struct LateralSurface {
  bool found = false;
  double s_mm = 0.0;  // along the axis from the tip
  int rays = 0;       // rays that agree
  int usable = 0;     // rays searched
};

// Rays beside the tip look this far ahead of it (beyond, the axial search alone).
constexpr double kLateralReachMm = 40.0;

LateralSurface FindLateralSurface(const imaging::Volume& v, const TipEstimate& tip, double ext,
                                  double rise_floor, const EdgeOptions& edge) {
  LateralSurface out;
  const double ds = 0.25;
  const double r = edge.lateral_radius_mm, back = edge.lateral_back_mm;
  Eigen::Vector3d u, w;
  PlaneBasis(tip.axis.direction, u, w);
  Eigen::Vector3d beam = BeamDirectionAt(v, tip.tip_mm);
  beam -= beam.dot(tip.axis.direction) * tip.axis.direction;
  const bool beam_known = beam.norm() > 0.2;
  if (beam_known) beam.normalize();
  const int bg_n = static_cast<int>(std::min(4.0, back - 2.0) / ds);
  // The eight rays are independent: searched in parallel, gathered in ray order.
  std::array<double, 8> ray_s;
  ray_s.fill(std::numeric_limits<double>::quiet_NaN());
  std::array<bool, 8> ray_used{};
  tbb::parallel_for(0, 8, [&](int k) {
    const double a = k * std::numbers::pi / 4;
    const Eigen::Vector3d o = r * (std::cos(a) * u + std::sin(a) * w);
    if (beam_known && o.normalized().dot(beam) > std::cos(0.7)) return;  // behind the wire
    ray_used[static_cast<std::size_t>(k)] = true;
    const Line3 ray{tip.tip_mm - back * tip.axis.direction + o, tip.axis.direction};
    Eigen::Vector3d ru, rw;
    PlaneBasis(ray.direction, ru, rw);
    const DiscProfile disc(v, ray, ru, rw, 0.5, DiscProfile::Reduce::kMean);
    LazyProfile profile(disc, ds, SampleCount(back + std::min(ext, kLateralReachMm), ds));
    if (static_cast<int>(profile.Upto(bg_n + 8).size()) < bg_n + 8) return;
    const double i = FirstSurface(profile, ds, bg_n, 0, bg_n, rise_floor, edge.dynamic_range_db);
    if (!std::isnan(i)) ray_s[static_cast<std::size_t>(k)] = i * ds - back;
  });
  std::vector<Eigen::Vector2d> xy;
  std::vector<double> sv;
  for (int k = 0; k < 8; ++k) {
    out.usable += ray_used[static_cast<std::size_t>(k)];
    if (std::isnan(ray_s[static_cast<std::size_t>(k)])) continue;
    const double a = k * std::numbers::pi / 4;
    xy.emplace_back(std::cos(a) * r, std::sin(a) * r);
    sv.push_back(ray_s[static_cast<std::size_t>(k)]);
  }
  // Robust plane fit.
  std::vector<bool> keep(sv.size(), true);
  auto count = [&] { return static_cast<int>(std::count(keep.begin(), keep.end(), true)); };
  while (count() >= 4) {
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < sv.size(); ++k)
      if (keep[k]) {
        const Eigen::Vector3d row(1.0, xy[k].x(), xy[k].y());
        ata += row * row.transpose();
        atb += row * sv[k];
      }
    const Eigen::Vector3d x = ata.ldlt().solve(atb);
    std::size_t worst = 0;
    double worst_res = -1;
    for (std::size_t k = 0; k < sv.size(); ++k)
      if (keep[k]) {
        const double res = std::abs(x[0] + x[1] * xy[k].x() + x[2] * xy[k].y() - sv[k]);
        if (res > worst_res) {
          worst_res = res;
          worst = k;
        }
      }
    if (worst_res <= 1.0) {
      out.s_mm = x[0];
      out.rays = count();
      // Half the searched rays at least must agree: a surface, not a speck.
      out.found = 2 * out.rays >= out.usable;
      return out;
    }
    keep[worst] = false;
  }
  return out;
}

// The wire's end near a surface at s_surface (along the axis from the detected tip, mm):
// when the tip is within ~2 mm of tissue, or presses into it, the bright run FindTip follows
// can bridge the gap and continue through the tissue, so its end lies inside or behind it.
// The wire echoes far brighter than tissue (20–40 dB): its level is the 75th percentile of
// the first-echo profile over 6…1 mm before the surface, and its end the first crossing of
// half that amplitude (over the volume's background) going forward from where the profile
// first reaches it, interpolated; searched up to the detected tip.
double WireEnd(const imaging::Volume& v, const TipEstimate& tip, double bg, double s_surface,
               const EdgeOptions& edge) {
  const double ds = 0.25;
  Eigen::Vector3d u, w;
  PlaneBasis(tip.axis.direction, u, w);
  const FirstEchoDiscProfile first(v, Line3{tip.tip_mm, tip.axis.direction}, u, w, 0.6,
                                   edge.tip_first_echo_mm);
  const double s_lo = std::min(s_surface, 0.0) - 6.0;
  std::vector<double> s_val, amp;
  for (double s = s_lo; s <= 0.5 + 1e-9; s += ds) {
    const double x = first(s);
    s_val.push_back(s);
    amp.push_back(std::isnan(x) ? 0.0 : EchoAmplitude(x, edge.dynamic_range_db));
  }
  std::vector<double> wire;
  for (std::size_t k = 0; k < s_val.size(); ++k)
    if (s_val[k] >= s_surface - 6.0 && s_val[k] <= s_surface - 1.0) wire.push_back(amp[k]);
  if (wire.size() < 4) return 0.0;
  std::sort(wire.begin(), wire.end());
  const double level = wire[wire.size() * 3 / 4];
  const double a_bg = EchoAmplitude(bg, edge.dynamic_range_db);
  const double cut = a_bg + edge.edge_fraction * (level - a_bg);
  std::size_t k = 0;
  while (k < amp.size() && amp[k] < cut) ++k;
  while (k + 1 < amp.size() && amp[k + 1] >= cut) ++k;
  if (k + 1 >= amp.size()) return 0.0;  // bright up to the detected tip: that tip
  const double x0 = amp[k], x1 = amp[k + 1];
  return s_val[k] + (x0 > x1 ? ds * std::clamp((x0 - cut) / (x0 - x1), 0.0, 1.0) : 0.0);
}

}  // namespace

TargetEstimate FindTarget(const imaging::Volume& v, const TipEstimate& tip, double bg,
                          const EdgeOptions& edge) {
  TargetEstimate out;
  const Line3 line = tip.axis;
  const double level = tip.line_level;
  const double ds = 0.25;
  const double ext = 0.5 * v.BoundingBoxMm().diagonal().norm() + 1;
  const double rise_floor = std::max(12.0, 0.1 * (level - bg));
  // Axial: forward from the tip, the mean over a 0.75 mm disc (the tissue ahead is a broad
  // surface, and averaging nine samples of its speckle steadies the profile where a max
  // would chase speckle peaks).
  const Line3 fwd{tip.tip_mm, line.direction};
  Eigen::Vector3d fu, fw;
  PlaneBasis(fwd.direction, fu, fw);
  const DiscProfile disc(v, fwd, fu, fw, 0.75, DiscProfile::Reduce::kMean);
  LazyProfile fp(disc, ds, SampleCount(ext * 2, ds));
  // From `from_mm` past the tip, the background measured over the next 4 mm (blood, or a
  // tank's water, scatters too; its speckle must not pass for the surface).
  // (or up to `bg_end_mm`, at least 1 mm, when a surface is expected sooner).
  auto axial = [&](double from_mm, double bg_end_mm = 1e9) {
    const int start = static_cast<int>(from_mm / ds);
    const int end = static_cast<int>(std::clamp(bg_end_mm, from_mm + 1.0, from_mm + 4.0) / ds);
    const double i = FirstSurface(fp, ds, start, start, end, rise_floor, edge.dynamic_range_db);
    return i * ds;
  };
  // The located surface met with the axis, in the axial profile: the surface fit over
  // −1.5…+2.5 mm around the lateral estimate when that window clears the tip's echo.
  auto refine = [&](double s_mm) {
    const int i0 = static_cast<int>(std::lround((s_mm - 1.5) / ds));
    const int i1 = static_cast<int>(std::lround((s_mm + 2.5) / ds));
    if (i0 * ds < 1.0 || i1 >= static_cast<int>(fp.Upto(i1 + 1).size())) return s_mm;
    const std::vector<double>& x = fp.Upto(i1 + 1);
    std::vector<double> amp;
    for (int k = i0; k <= i1; ++k)
      amp.push_back(EchoAmplitude(x[static_cast<std::size_t>(k)], edge.dynamic_range_db));
    const double s = (i0 + FitSurfaceEcho(amp, ds)) * ds;
    return std::abs(s - s_mm) <= 0.75 ? s : s_mm;
  };
  const double s_axial = axial(2.0);
  const LateralSurface lateral = FindLateralSurface(v, tip, ext, rise_floor, edge);
  std::optional<double> s_target;
  double s_tip = 0.0;  // the tip, re-located, along the axis from the detected one
  if (lateral.found) {
    const double sl = lateral.s_mm;
    if (sl < edge.close_gap_mm) {
      // Close: the tip's echo and the tissue's merge on the axis; the surface beside the tip
      // is the evidence, and the wire's end is looked for before it.
      s_tip = std::min(0.0, WireEnd(v, tip, bg, sl, edge));
      s_target = sl;
    } else if (!std::isnan(s_axial) && std::abs(s_axial - sl) <= 1.5) {
      s_target = s_axial;
    } else if (!std::isnan(s_axial) && s_axial < sl - 1.5 && s_axial > edge.doubt_gap_mm) {
      // Something on the axis before the surface around it, well past the tip: a blip of
      // speckle when the axis, searched past it, meets the lateral surface. Else, at least
      // close_gap_mm ahead, it is what the catheter points at (the rays beside the tip can
      // miss a small or curved structure on the axis, or meet clutter); closer, which one
      // the catheter points at is ambiguous (not found).
      const double further = axial(s_axial + 2.0, sl - 1.0);
      if (!std::isnan(further) && std::abs(further - sl) <= 1.5) {
        s_target = further;
      } else if (s_axial >= edge.close_gap_mm) {
        s_target = s_axial;
      }
    } else if (!std::isnan(s_axial) && s_axial > sl + 1.5 && sl >= edge.close_gap_mm) {
      // On the axis, beyond a surface found only beside the tip, far from it: the rays beside
      // the tip met something (clutter, a neighbouring wall) the axis does not.
      s_target = s_axial;
    } else {
      // No axial surface, one beyond the lateral one, or one hugging the tip that the
      // surface around it does not confirm: the real surface is the lateral one.
      s_target = refine(sl);
    }
  } else if (!std::isnan(s_axial)) {
    if (s_axial > edge.doubt_gap_mm) {
      s_target = s_axial;
    } else {
      // Unconfirmed and hugging the tip: look further along the axis.
      const double further = axial(s_axial + 2.0);
      if (!std::isnan(further)) s_target = further;
    }
  }
  if (!s_target) return out;
  out.found = true;
  out.tip_mm = tip.tip_mm + s_tip * line.direction;
  const double gap = *s_target - s_tip;
  out.contact = lateral.found && gap <= edge.contact_gap_mm;
  out.gap_mm = out.contact ? 0.0 : gap;
  out.indentation_mm = std::max(0.0, -gap);
  // Pressed into the tissue, the target stays the surface around the tip (behind it).
  out.target_mm =
      tip.tip_mm + (out.contact ? std::min(*s_target, s_tip) : *s_target) * line.direction;
  return out;
}

}  // namespace echoservo::tracking
