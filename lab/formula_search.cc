#include "lab/formula_search.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

// How the search works (see the header for the grammar):
// - The target is fitted in units of its weighted spread (so any unit fits alike); the
//   constants, offset and errors are reported in the target's unit.
// - Forms linear in their constant (linear, quadratic, cubic and the pair forms) are solved
//   in closed form (weighted least squares with the offset), per fold from the fold sums.
// - Every other form is a·g(x; θ) + offset. Candidate starts for θ come from the data
//   (periodogram for the sine, the binned target's steepest change, bend and extreme for
//   step, ramp and bump, fractions of the range for τ, a ladder of exponents for the power);
//   the amplitude and offset of each candidate are solved linearly (variable projection) and
//   the best `starts` are fitted with Ceres (autodiff, bounded) on a coarse subsample (at
//   most kMaxStartSamples); the best of those is polished on the fit subsample (at most
//   kMaxFitSamples) and starts each fold's fit (on the other folds).
// - Subsamples: every k-th sample of each fold, in the caller's order (deterministic). Every
//   held-out score (linear forms too, so that all compare on the same samples) is over the
//   fit subsample; `mse` over every sample. With more samples than kMaxFitSamples, the
//   nonlinear forms on the Pareto front are refitted on every sample for the reported
//   constants; the others report their subsample fit (refitting all of them on 50 000
//   samples would take most of the time allowed).
// - The folds' fits start at the all-data optimum rather than a fresh multistart each:
//   cheap, but a little optimistic — on pure noise the best form gains a few tenths of a
//   percent of the variance over the offset alone (3000 samples).
// - With an offset, exp_rise and exp_decay are one family: both report the better of their
//   two fits (same held-out error) and the one that leaves less to the offset sorts first.
// - A form whose fit fails (input with fewer than 3 distinct values, no finite start, Ceres
//   unusable, constants not finite) is kept in the list with held_out_mse = mse = +inf, zero
//   constants and words starting "(fit failed)"; it sorts last and never enters the front.
// - Internally the sine's phase is taken at the middle of the range and the exponentials
//   are anchored at the smallest input (better conditioned); the reported constants are
//   converted back to the header's forms in x as is.
// - Form names: the header's, with the scaled pair forms named scaled_square (c·x·y²) and
//   scaled_abs (c·x·|y|).

namespace echoservo::lab {
namespace {
// Named, so that the lab's unity batches keep these helpers apart from other files'.
namespace formula_search_impl {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = std::numbers::pi;
constexpr std::size_t kMaxFitSamples = 4000;
constexpr std::size_t kMaxStartSamples = 1000;
constexpr double kMaxExponent = 700.0;  // exp() of more overflows
constexpr int kPeriodogramBins = 1024;
constexpr int kProfileBins = 64;

enum class Kind {
  kLinear,
  kQuadratic,
  kCubic,
  kPower,
  kBump,
  kSine,
  kStep,
  kRamp,
  kExpRise,
  kExpDecay,
  kProduct,
  kScaledSquare,
  kScaledAbs
};

struct FormSpec {
  Kind kind;
  const char* name;
  int variables;
  int complexity;
};

constexpr FormSpec kForms[] = {
    {Kind::kLinear, "linear", 1, 1},
    {Kind::kQuadratic, "quadratic", 1, 1},
    {Kind::kCubic, "cubic", 1, 1},
    {Kind::kPower, "power", 1, 2},
    {Kind::kBump, "bump", 1, 3},
    {Kind::kSine, "sine", 1, 3},
    {Kind::kStep, "step", 1, 3},
    {Kind::kRamp, "ramp", 1, 3},
    {Kind::kExpRise, "exp_rise", 1, 2},
    {Kind::kExpDecay, "exp_decay", 1, 2},
    {Kind::kProduct, "product", 2, 1},
    {Kind::kScaledSquare, "scaled_square", 2, 1},
    {Kind::kScaledAbs, "scaled_abs", 2, 1},
};

const FormSpec* FindForm(const std::string& name) {
  for (const FormSpec& f : kForms) {
    if (name == f.name) return &f;
  }
  return nullptr;
}

bool IsLinearForm(Kind k) {
  return k == Kind::kLinear || k == Kind::kQuadratic || k == Kind::kCubic || k == Kind::kProduct ||
         k == Kind::kScaledSquare || k == Kind::kScaledAbs;
}

// The column of a form linear in its single constant.
double Basis(Kind k, double x, double y) {
  switch (k) {
    case Kind::kLinear:
      return x;
    case Kind::kQuadratic:
      return x * x;
    case Kind::kCubic:
      return x * x * x;
    case Kind::kProduct:
      return x * y;
    case Kind::kScaledSquare:
      return x * y * y;
    case Kind::kScaledAbs:
      return x * std::abs(y);
    default:
      return 0.0;
  }
}

// ---------------------------------------------------------------------------------------
// Nonlinear forms in their internal parameters: p[0] the linear amplitude (c, a, slope),
// then the nonlinear constants, then the offset when fitted.

struct Frame {
  double centre = 0.0;       // the sine's phase reference
  double rise_shift = 0.0;   // anchor of exp_rise (the smallest input with an offset, else 0)
  double decay_shift = 0.0;  // anchor of exp_decay (the smallest input)
};

template <typename T>
T Softplus(const T& z) {
  using std::exp;
  using std::log1p;
  if (z > 0.0) return z + log1p(exp(-z));
  return log1p(exp(z));
}

template <typename T>
T Shape(Kind kind, const T* p, double x, const Frame& f) {
  using std::exp;
  using std::sin;
  switch (kind) {
    case Kind::kPower: {
      const double ax = std::abs(x);
      if (ax == 0.0) return T(0.0);
      return p[0] * exp(p[1] * std::log(ax));
    }
    case Kind::kBump: {
      const T d = (x - p[1]) / p[2];
      return p[0] * exp(-d * d);
    }
    case Kind::kSine:
      return p[0] * sin(2.0 * kPi * (x - f.centre) / p[1] + p[2]);
    case Kind::kStep: {
      const T z = (x - p[1]) / p[2];
      if (z >= 0.0) return p[0] / (1.0 + exp(-z));
      const T e = exp(z);
      return p[0] * e / (1.0 + e);
    }
    case Kind::kRamp:
      return p[0] * p[2] * Softplus(T((x - p[1]) / p[2]));
    case Kind::kExpRise: {
      T z = -(x - f.rise_shift) / p[1];
      if (z > kMaxExponent) z = T(kMaxExponent);
      return p[0] * (1.0 - exp(z));
    }
    case Kind::kExpDecay: {
      T z = -(x - f.decay_shift) / p[1];
      if (z > kMaxExponent) z = T(kMaxExponent);
      return p[0] * exp(z);
    }
    default:
      return T(0.0);
  }
}

// One nonlinear fit's data: the full arrays, selected by an index list per fit.
struct Curve {
  Kind kind = Kind::kSine;
  Frame frame;
  bool offset = true;
  int size = 0;  // internal parameters, the offset included
  const double* x = nullptr;
  const double* t = nullptr;
  const double* sw = nullptr;  // √weight
  std::vector<double> lower, upper;

  double Predict(const double* p, std::size_t i) const {
    return Shape<double>(kind, p, x[i], frame) + (offset ? p[size - 1] : 0.0);
  }
  // Weighted sum of squares over `idx`.
  double Cost(const std::vector<double>& p, const std::vector<int>& idx) const {
    double s = 0.0;
    for (const int i : idx) {
      const auto k = static_cast<std::size_t>(i);
      const double r = sw[k] * (Predict(p.data(), k) - t[k]);
      s += r * r;
    }
    return s;
  }
};

template <Kind K, int N>
struct ShapeResiduals {
  const Curve* curve;
  const std::vector<int>* idx;
  template <typename T>
  bool operator()(const T* p, T* r) const {
    const Curve& c = *curve;
    const T offset = c.offset ? p[N - 1] : T(0.0);
    for (std::size_t i = 0; i < idx->size(); ++i) {
      const auto k = static_cast<std::size_t>((*idx)[i]);
      r[i] = c.sw[k] * (Shape(K, p, c.x[k], c.frame) + offset - c.t[k]);
    }
    return true;
  }
};

template <Kind K>
ceres::CostFunction* MakeCostOf(const Curve& c, const std::vector<int>& idx) {
  const int residuals = static_cast<int>(idx.size());
  switch (c.size) {
    case 2:
      return new ceres::AutoDiffCostFunction<ShapeResiduals<K, 2>, ceres::DYNAMIC, 2>(
          new ShapeResiduals<K, 2>{&c, &idx}, residuals);
    case 3:
      return new ceres::AutoDiffCostFunction<ShapeResiduals<K, 3>, ceres::DYNAMIC, 3>(
          new ShapeResiduals<K, 3>{&c, &idx}, residuals);
    case 4:
      return new ceres::AutoDiffCostFunction<ShapeResiduals<K, 4>, ceres::DYNAMIC, 4>(
          new ShapeResiduals<K, 4>{&c, &idx}, residuals);
    default:
      return nullptr;
  }
}

// One cost function per form (the form a template constant: no switch per sample).
ceres::CostFunction* MakeCost(const Curve& c, const std::vector<int>& idx) {
  switch (c.kind) {
    case Kind::kPower:
      return MakeCostOf<Kind::kPower>(c, idx);
    case Kind::kBump:
      return MakeCostOf<Kind::kBump>(c, idx);
    case Kind::kSine:
      return MakeCostOf<Kind::kSine>(c, idx);
    case Kind::kStep:
      return MakeCostOf<Kind::kStep>(c, idx);
    case Kind::kRamp:
      return MakeCostOf<Kind::kRamp>(c, idx);
    case Kind::kExpRise:
      return MakeCostOf<Kind::kExpRise>(c, idx);
    case Kind::kExpDecay:
      return MakeCostOf<Kind::kExpDecay>(c, idx);
    default:
      return nullptr;
  }
}

bool AllFinite(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double a) { return std::isfinite(a); });
}

void Clamp(const Curve& c, std::vector<double>& p) {
  for (std::size_t j = 0; j < p.size(); ++j) p[j] = std::clamp(p[j], c.lower[j], c.upper[j]);
}

// Fits `p` (in place) on the samples `idx`; false when no usable finite solution.
bool Fit(const Curve& c, const std::vector<int>& idx, std::vector<double>& p, int max_iterations,
         double tolerance) {
  if (static_cast<int>(idx.size()) < c.size + 1) return false;
  Clamp(c, p);
  if (!AllFinite(p) || !std::isfinite(c.Cost(p, idx))) return false;
  ceres::CostFunction* cost = MakeCost(c, idx);
  if (cost == nullptr) return false;
  ceres::Problem problem;
  problem.AddResidualBlock(cost, nullptr, p.data());
  for (int j = 0; j < c.size; ++j) {
    const auto u = static_cast<std::size_t>(j);
    if (std::isfinite(c.lower[u])) problem.SetParameterLowerBound(p.data(), j, c.lower[u]);
    if (std::isfinite(c.upper[u])) problem.SetParameterUpperBound(p.data(), j, c.upper[u]);
  }
  ceres::Solver::Options so;
  so.max_num_iterations = max_iterations;
  so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.num_threads = 1;
  so.function_tolerance = tolerance;
  so.gradient_tolerance = 1e-14;  // absolute: the inputs' unit would matter
  so.parameter_tolerance = tolerance;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  return summary.IsSolutionUsable() && AllFinite(p) && std::isfinite(summary.final_cost);
}

// Variable projection: with the nonlinear constants of `p` fixed, the amplitude p[0] and the
// offset that minimise the weighted squares over `idx`; returns that sum (+inf if not finite).
double Project(const Curve& c, std::vector<double>& p, const std::vector<int>& idx) {
  std::vector<double> unit = p;
  unit[0] = 1.0;
  if (c.offset) unit.back() = 0.0;
  std::vector<double> g(idx.size());
  double sgg = 0.0, sg = 0.0, s1 = 0.0, sgt = 0.0, st = 0.0;
  for (std::size_t i = 0; i < idx.size(); ++i) {
    const auto k = static_cast<std::size_t>(idx[i]);
    g[i] = Shape<double>(c.kind, unit.data(), c.x[k], c.frame);
    const double w = c.sw[k] * c.sw[k];
    sgg += w * g[i] * g[i];
    sg += w * g[i];
    s1 += w;
    sgt += w * g[i] * c.t[k];
    st += w * c.t[k];
  }
  double a = 0.0, o = 0.0;
  if (c.offset) {
    const double det = sgg * s1 - sg * sg;
    if (s1 > 0.0 && det > 1e-12 * sgg * s1) {
      a = (sgt * s1 - sg * st) / det;
      o = (sgg * st - sg * sgt) / det;
    } else if (s1 > 0.0) {
      o = st / s1;
    }
  } else if (sgg > 0.0) {
    a = sgt / sgg;
  }
  double sse = 0.0;
  for (std::size_t i = 0; i < idx.size(); ++i) {
    const auto k = static_cast<std::size_t>(idx[i]);
    const double r = c.sw[k] * (a * g[i] + o - c.t[k]);
    sse += r * r;
  }
  p[0] = a;
  if (c.offset) p.back() = o;
  return std::isfinite(sse) && std::isfinite(a) ? sse : kInf;
}

// ---------------------------------------------------------------------------------------
// The data along one variable, for the starts.

struct Axis {
  double min = 0.0, max = 0.0, range = 0.0;
  double spacing = 0.0;  // median gap between distinct values
  std::size_t distinct = 0;
};

Axis Describe(const std::vector<double>& x, const std::vector<int>& idx) {
  std::vector<double> v;
  v.reserve(idx.size());
  for (const int i : idx) v.push_back(x[static_cast<std::size_t>(i)]);
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  Axis a;
  if (v.empty()) return a;
  a.min = v.front();
  a.max = v.back();
  a.range = a.max - a.min;
  a.distinct = v.size();
  if (v.size() >= 2) {
    std::vector<double> gap(v.size() - 1);
    for (std::size_t i = 0; i + 1 < v.size(); ++i) gap[i] = v[i + 1] - v[i];
    std::nth_element(gap.begin(), gap.begin() + static_cast<std::ptrdiff_t>(gap.size() / 2),
                     gap.end());
    a.spacing = gap[gap.size() / 2];
  }
  return a;
}

// Weighted means of the target in equal bins along x (empty bins left out).
struct Profile {
  std::vector<double> x, mean, weight;
};

Profile Bin(const Curve& c, const std::vector<int>& idx, const Axis& a, int bins) {
  bins = std::max(bins, 2);
  std::vector<double> w(static_cast<std::size_t>(bins), 0.0), s(w.size(), 0.0);
  const double h = a.range / (bins - 1);
  for (const int i : idx) {
    const auto k = static_cast<std::size_t>(i);
    const double ww = c.sw[k] * c.sw[k];
    const auto b = static_cast<std::size_t>(
        std::clamp(std::lround((c.x[k] - a.min) / h), 0L, static_cast<long>(bins - 1)));
    w[b] += ww;
    s[b] += ww * c.t[k];
  }
  Profile p;
  for (std::size_t b = 0; b < w.size(); ++b) {
    if (w[b] <= 0.0) continue;
    p.x.push_back(a.min + static_cast<double>(b) * h);
    p.mean.push_back(s[b] / w[b]);
    p.weight.push_back(w[b]);
  }
  return p;
}

std::vector<double> Smooth(const std::vector<double>& m) {
  if (m.size() < 3) return m;
  std::vector<double> s(m.size());
  s.front() = m.front();
  s.back() = m.back();
  for (std::size_t i = 1; i + 1 < m.size(); ++i)
    s[i] = 0.25 * m[i - 1] + 0.5 * m[i] + 0.25 * m[i + 1];
  return s;
}

// Indices of the `count` largest values of `score` (descending).
std::vector<std::size_t> TopIndices(const std::vector<double>& score, std::size_t count) {
  std::vector<std::size_t> order(score.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return score[a] > score[b] || (score[a] == score[b] && a < b);
  });
  if (order.size() > count) order.resize(count);
  return order;
}

// A start of the internal parameters: amplitude 1 (projected later), offset 0.
std::vector<double> Start(const Curve& c, std::initializer_list<double> nonlinear) {
  std::vector<double> p(static_cast<std::size_t>(c.size), 0.0);
  p[0] = 1.0;
  std::size_t j = 1;
  for (const double v : nonlinear) p[j++] = v;
  return p;
}

// Sine: least-squares sine (with the offset) per candidate period of the binned target,
// over frequencies from half a cycle to one cycle per 3 spacings; the best local maxima.
std::vector<std::vector<double>> SineStarts(const Curve& c, const std::vector<int>& idx,
                                            const Axis& a, int count) {
  std::vector<std::vector<double>> out;
  const double spacing = a.spacing > 0.0 ? a.spacing : a.range;
  const int bins = static_cast<int>(
      std::clamp(std::lround(a.range / spacing) + 1, 2L, static_cast<long>(kPeriodogramBins)));
  // Weighted target per bin on a uniform grid (empty bins weigh nothing).
  const double h = a.range / (bins - 1);
  std::vector<double> bw(static_cast<std::size_t>(bins), 0.0), bm(bw.size(), 0.0);
  for (const int i : idx) {
    const auto k = static_cast<std::size_t>(i);
    const auto b = static_cast<std::size_t>(
        std::clamp(std::lround((c.x[k] - a.min) / h), 0L, static_cast<long>(bins - 1)));
    bw[b] += c.sw[k] * c.sw[k];
    bm[b] += c.sw[k] * c.sw[k] * c.t[k];
  }
  double sw = 0.0, sm = 0.0;
  for (std::size_t b = 0; b < bw.size(); ++b) {
    sw += bw[b];
    sm += bm[b];
    if (bw[b] > 0.0) bm[b] /= bw[b];
  }
  const double mean = c.offset && sw > 0.0 ? sm / sw : 0.0;
  const double f_min = 0.5 / a.range;
  const double f_max = 1.0 / (3.0 * std::max(spacing, h));
  const double df = 0.25 / a.range;
  std::vector<double> freq, gain, amp_sin, amp_cos;
  for (double f = f_min; f <= f_max; f += df) {
    double ss = 0.0, cc = 0.0, sc = 0.0, s1 = 0.0, c1 = 0.0, sy = 0.0, cy = 0.0;
    const double th0 = 2.0 * kPi * f * (a.min - c.frame.centre), dth = 2.0 * kPi * f * h;
    const double cd = std::cos(dth), sd = std::sin(dth);
    double s = 0.0, co = 1.0;
    for (std::size_t b = 0; b < bw.size(); ++b) {
      if (b % 128 == 0) {  // exact now and then, the rotation in between
        const double th = th0 + static_cast<double>(b) * dth;
        s = std::sin(th);
        co = std::cos(th);
      } else {
        const double s_next = s * cd + co * sd;
        co = co * cd - s * sd;
        s = s_next;
      }
      const double w = bw[b];
      if (w <= 0.0) continue;
      const double y = bm[b] - mean;
      ss += w * s * s;
      cc += w * co * co;
      sc += w * s * co;
      s1 += w * s;
      c1 += w * co;
      sy += w * s * y;
      cy += w * co * y;
    }
    if (c.offset && sw > 0.0) {  // centre the columns: the offset is fitted alongside
      ss -= s1 * s1 / sw;
      cc -= c1 * c1 / sw;
      sc -= s1 * c1 / sw;
    }
    const double det = ss * cc - sc * sc;
    if (!(det > 1e-12 * ss * cc) || ss <= 0.0 || cc <= 0.0) continue;
    const double A = (sy * cc - cy * sc) / det;
    const double B = (cy * ss - sy * sc) / det;
    freq.push_back(f);
    gain.push_back(A * sy + B * cy);
    amp_sin.push_back(A);
    amp_cos.push_back(B);
  }
  std::vector<double> peak(gain.size(), -kInf);
  for (std::size_t i = 0; i < gain.size(); ++i) {
    const bool left = i == 0 || gain[i] >= gain[i - 1];
    const bool right = i + 1 == gain.size() || gain[i] >= gain[i + 1];
    if (left && right) peak[i] = gain[i];
  }
  for (const std::size_t i : TopIndices(peak, static_cast<std::size_t>(count))) {
    if (!std::isfinite(peak[i])) break;
    std::vector<double> p = Start(c, {1.0 / freq[i], std::atan2(amp_cos[i], amp_sin[i])});
    out.push_back(std::move(p));
  }
  // A slow sine over the whole range, in case the grid found nothing.
  out.push_back(Start(c, {a.range, 0.0}));
  return out;
}

std::vector<std::vector<double>> StepRampStarts(const Curve& c, const std::vector<int>& idx,
                                                const Axis& a) {
  const Profile prof = Bin(c, idx, a, kProfileBins);
  const std::vector<double> m = Smooth(prof.mean);
  std::vector<double> where;
  if (c.kind == Kind::kStep) {
    // Where the binned target changes fastest.
    std::vector<double> d;
    for (std::size_t k = 0; k + 1 < m.size(); ++k)
      d.push_back(std::abs(prof.mean[k + 1] - prof.mean[k]));
    for (const std::size_t k : TopIndices(d, 3)) where.push_back(0.5 * (prof.x[k] + prof.x[k + 1]));
    for (const double q : {0.25, 0.5, 0.75}) where.push_back(a.min + q * a.range);
  } else {
    // Where it bends most.
    std::vector<double> dd(m.size(), 0.0);
    for (std::size_t k = 1; k + 1 < m.size(); ++k) {
      const double h1 = prof.x[k] - prof.x[k - 1], h2 = prof.x[k + 1] - prof.x[k];
      dd[k] = std::abs((m[k + 1] - m[k]) / h2 - (m[k] - m[k - 1]) / h1);
    }
    for (const std::size_t k : TopIndices(dd, 3)) {
      if (dd[k] > 0.0) where.push_back(prof.x[k]);
    }
    for (const double q : {0.2, 0.4, 0.6, 0.8}) where.push_back(a.min + q * a.range);
  }
  std::vector<std::vector<double>> out;
  for (const double x0 : where) {
    for (const double wf : {1.0 / 50.0, 1.0 / 200.0, 1.0 / 10.0}) {
      out.push_back(Start(c, {x0, wf * a.range}));
    }
  }
  return out;
}

std::vector<std::vector<double>> BumpStarts(const Curve& c, const std::vector<int>& idx,
                                            const Axis& a) {
  const Profile prof = Bin(c, idx, a, kProfileBins);
  const std::vector<double> m = Smooth(prof.mean);
  std::vector<std::vector<double>> out;
  if (!m.empty()) {
    std::vector<double> sorted = m;
    std::nth_element(sorted.begin(),
                     sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double base = sorted[sorted.size() / 2];
    std::vector<double> dev(m.size());
    for (std::size_t k = 0; k < m.size(); ++k) dev[k] = m[k] - base;
    const auto hi =
        static_cast<std::size_t>(std::max_element(dev.begin(), dev.end()) - dev.begin());
    const auto lo =
        static_cast<std::size_t>(std::min_element(dev.begin(), dev.end()) - dev.begin());
    for (const std::size_t k : {hi, lo}) {
      const double half = 0.5 * dev[k];
      if (half == 0.0) continue;
      // Walk out to half height on each side (linear interpolation between bins).
      auto cross = [&](std::size_t j, std::size_t prev) {
        const double f = (dev[prev] - half) / (dev[prev] - dev[j]);
        return prof.x[prev] + f * (prof.x[j] - prof.x[prev]);
      };
      double left = prof.x.front(), right = prof.x.back();
      for (std::size_t j = k; j > 0; --j) {
        if ((dev[j - 1] - half) * half <= 0.0) {
          left = cross(j - 1, j);
          break;
        }
      }
      for (std::size_t j = k; j + 1 < m.size(); ++j) {
        if ((dev[j + 1] - half) * half <= 0.0) {
          right = cross(j + 1, j);
          break;
        }
      }
      const double fwhm = std::max(right - left, a.range / 200.0);
      const double w = fwhm / (2.0 * std::sqrt(std::log(2.0)));
      for (const double f : {1.0, 0.5, 2.0}) out.push_back(Start(c, {prof.x[k], f * w}));
    }
  }
  for (const double q : {0.25, 0.5, 0.75})
    out.push_back(Start(c, {a.min + q * a.range, a.range / 8.0}));
  return out;
}

std::vector<std::vector<double>> Starts(const Curve& c, const std::vector<int>& idx, const Axis& a,
                                        int starts) {
  switch (c.kind) {
    case Kind::kSine:
      return SineStarts(c, idx, a, std::max(starts, 3));
    case Kind::kStep:
    case Kind::kRamp:
      return StepRampStarts(c, idx, a);
    case Kind::kBump:
      return BumpStarts(c, idx, a);
    case Kind::kExpRise:
    case Kind::kExpDecay: {
      std::vector<std::vector<double>> out;
      for (const double f : {0.03, 0.1, 0.2, 0.4, 1.0, 3.0}) out.push_back(Start(c, {f * a.range}));
      return out;
    }
    case Kind::kPower: {
      std::vector<std::vector<double>> out;
      for (const double p : {0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0})
        out.push_back(Start(c, {p}));
      return out;
    }
    default:
      return {};
  }
}

void SetBounds(Curve& c, const Axis& a) {
  const auto n = static_cast<std::size_t>(c.size);
  c.lower.assign(n, -kInf);
  c.upper.assign(n, kInf);
  const double tiny = a.range / 1000.0;
  switch (c.kind) {
    case Kind::kPower:
      c.lower[1] = 0.2;
      c.upper[1] = 4.0;
      break;
    case Kind::kBump:
      c.lower[1] = a.min;
      c.upper[1] = a.max;
      c.lower[2] = tiny;
      c.upper[2] = 2.0 * a.range;
      break;
    case Kind::kSine:
      c.lower[1] = 2.0 * (a.spacing > 0.0 ? a.spacing : tiny);
      c.upper[1] = 2.0 * a.range;
      break;
    case Kind::kStep:
    case Kind::kRamp:
      c.lower[1] = a.min;
      c.upper[1] = a.max;
      c.lower[2] = tiny;
      c.upper[2] = a.range;
      break;
    case Kind::kExpRise:
    case Kind::kExpDecay:
      c.lower[1] = tiny;
      c.upper[1] = 10.0 * a.range;
      break;
    default:
      break;
  }
}

// ---------------------------------------------------------------------------------------
// The data once checked, and the fit of one form.

struct Data {
  std::size_t n = 0;
  int variables = 1;
  std::vector<double> x, y, t, sw;
  std::vector<int> fold_index;  // 0..folds−1, −1: never held out
  int folds = 0;
  bool offset = true;
  double scale = 1.0;       // the target is fitted divided by this (its weighted spread)
  std::vector<int> all;     // 0..n−1
  std::vector<int> sub;     // the fit subsample
  std::vector<int> coarse;  // a sparser one for the many starts
  std::vector<std::vector<int>> train;  // per fold: sub without that fold
  std::vector<std::vector<int>> test;   // per fold: sub in that fold
};

struct FitOutcome {
  bool ok = false;
  std::vector<double> p;  // internal (nonlinear) or {c, offset} (linear)
  double mse = kInf;
  double held_out_mse = kInf;
};

double WeightOf(const Data& d, const std::vector<int>& idx) {
  double s = 0.0;
  for (const int i : idx)
    s += d.sw[static_cast<std::size_t>(i)] * d.sw[static_cast<std::size_t>(i)];
  return s;
}

// Weighted least squares of t on the form's column (and 1 with the offset).
struct LinearSums {
  double bb = 0.0, b = 0.0, w = 0.0, bt = 0.0, t = 0.0;
  void Add(double basis, double target, double weight) {
    bb += weight * basis * basis;
    b += weight * basis;
    w += weight;
    bt += weight * basis * target;
    t += weight * target;
  }
  LinearSums Minus(const LinearSums& o) const {
    return {bb - o.bb, b - o.b, w - o.w, bt - o.bt, t - o.t};
  }
  // {c, offset}
  std::pair<double, double> Solve(bool offset) const {
    if (offset) {
      const double det = bb * w - b * b;
      if (w > 0.0 && det > 1e-12 * bb * w) return {(bt * w - b * t) / det, (bb * t - b * bt) / det};
      return {0.0, w > 0.0 ? t / w : 0.0};
    }
    return {bb > 0.0 ? bt / bb : 0.0, 0.0};
  }
};

FitOutcome FitLinear(const Data& d, Kind kind) {
  FitOutcome out;
  auto basis = [&](std::size_t i) { return Basis(kind, d.x[i], d.variables > 1 ? d.y[i] : 0.0); };
  // Held out, on the subsample: fold sums subtracted from the totals.
  LinearSums total;
  std::vector<LinearSums> per_fold(static_cast<std::size_t>(d.folds));
  for (const int i : d.sub) {
    const auto k = static_cast<std::size_t>(i);
    const double w = d.sw[k] * d.sw[k];
    total.Add(basis(k), d.t[k], w);
    if (d.fold_index[k] >= 0)
      per_fold[static_cast<std::size_t>(d.fold_index[k])].Add(basis(k), d.t[k], w);
  }
  double sse = 0.0, weight = 0.0;
  for (int f = 0; f < d.folds; ++f) {
    const auto [c, o] = total.Minus(per_fold[static_cast<std::size_t>(f)]).Solve(d.offset);
    for (const int i : d.test[static_cast<std::size_t>(f)]) {
      const auto k = static_cast<std::size_t>(i);
      const double r = d.sw[k] * (c * basis(k) + o - d.t[k]);
      sse += r * r;
      weight += d.sw[k] * d.sw[k];
    }
  }
  out.held_out_mse = weight > 0.0 ? sse / weight : kInf;
  // Every sample.
  LinearSums all;
  for (std::size_t k = 0; k < d.n; ++k) all.Add(basis(k), d.t[k], d.sw[k] * d.sw[k]);
  const auto [c, o] = all.Solve(d.offset);
  double in = 0.0;
  for (std::size_t k = 0; k < d.n; ++k) {
    const double r = d.sw[k] * (c * basis(k) + o - d.t[k]);
    in += r * r;
  }
  out.p = {c, o};
  out.mse = in / all.w;
  out.ok = std::isfinite(c) && std::isfinite(o) && std::isfinite(out.mse) &&
           std::isfinite(out.held_out_mse);
  if (!out.ok) out.mse = out.held_out_mse = kInf;
  return out;
}

FitOutcome FitNonlinear(const Data& d, const Curve& c, const Axis& a, int starts) {
  FitOutcome out;
  if (!(a.range > 0.0) || a.distinct < 3) return out;
  // Candidate starts, amplitude and offset solved linearly, the best `starts` fitted on the
  // coarse subsample; the best of those polished on the subsample (for the sine also the
  // best candidate as it was: the coarse subsample may alias a short period).
  std::vector<std::pair<double, std::vector<double>>> ranked;
  for (std::vector<double>& p : Starts(c, d.sub, a, starts)) {
    Clamp(c, p);
    const double sse = Project(c, p, d.coarse);
    if (std::isfinite(sse)) ranked.emplace_back(sse, std::move(p));
  }
  std::stable_sort(ranked.begin(), ranked.end(),
                   [](const auto& l, const auto& r) { return l.first < r.first; });
  if (ranked.size() > static_cast<std::size_t>(starts))
    ranked.resize(static_cast<std::size_t>(starts));
  if (ranked.empty()) return out;
  std::vector<std::vector<double>> polish;
  if (c.kind == Kind::kSine) polish.push_back(ranked.front().second);
  double coarse_best = kInf;
  for (auto& [sse, p] : ranked) {
    if (!Fit(c, d.coarse, p, 25, 1e-6)) continue;
    const double cost = c.Cost(p, d.coarse);
    if (cost < coarse_best) {
      coarse_best = cost;
      if (polish.empty() || (c.kind == Kind::kSine && polish.size() < 2)) polish.emplace_back();
      polish.back() = p;
    }
  }
  double best_cost = kInf;
  std::vector<double> best;
  for (std::vector<double>& p : polish) {
    if (!Fit(c, d.sub, p, 30, 1e-7)) continue;
    const double cost = c.Cost(p, d.sub);
    if (cost < best_cost) {
      best_cost = cost;
      best = p;
    }
  }
  if (best.empty()) return out;
  // Held out: each fold predicted from a fit on the others, started at the best fit.
  double sse = 0.0, weight = 0.0;
  for (int f = 0; f < d.folds; ++f) {
    std::vector<double> p = best;
    if (!Fit(c, d.train[static_cast<std::size_t>(f)], p, 6, 1e-6)) return out;
    for (const int i : d.test[static_cast<std::size_t>(f)]) {
      const auto k = static_cast<std::size_t>(i);
      const double r = d.sw[k] * (c.Predict(p.data(), k) - d.t[k]);
      sse += r * r;
      weight += d.sw[k] * d.sw[k];
    }
  }
  if (!(weight > 0.0) || !std::isfinite(sse)) return out;
  // In sample over every sample (the constants refitted on them later, see Refit).
  const double in = c.Cost(best, d.all) / WeightOf(d, d.all);
  if (!std::isfinite(in)) return out;
  out.ok = true;
  out.p = std::move(best);
  out.mse = in;
  out.held_out_mse = sse / weight;
  return out;
}

// The fit refitted on every sample (when the subsample left some out).
void Refit(const Data& d, const Curve& c, FitOutcome& fit) {
  if (!fit.ok || d.sub.size() == d.n) return;
  std::vector<double> p = fit.p;
  if (!Fit(c, d.all, p, 6, 1e-6)) return;
  const double in = c.Cost(p, d.all) / WeightOf(d, d.all);
  if (!std::isfinite(in)) return;
  fit.p = std::move(p);
  fit.mse = in;
}

// ---------------------------------------------------------------------------------------
// Presentation: names, units, expression and words.

std::string Number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

std::string UnitOrOne(const std::string& u) { return u.empty() ? "1" : u; }

// Whether `u` holds one of `ops` outside parentheses.
bool HasTopLevel(const std::string& u, const char* ops) {
  int depth = 0;
  for (const char ch : u) {
    if (ch == '(') ++depth;
    if (ch == ')') --depth;
    if (depth == 0 && std::strchr(ops, ch) != nullptr) return true;
  }
  return false;
}

bool Compound(const std::string& u) { return HasTopLevel(u, "*/^ "); }

std::string UnitPow(const std::string& u, const std::string& k) {
  if (u == "1") return "1";
  return (Compound(u) ? "(" + u + ")" : u) + "^" + k;
}

std::string UnitMul(const std::string& a, const std::string& b) {
  if (a == "1") return b;
  if (b == "1") return a;
  if (a == b) return UnitPow(a, "2");
  return a + "*" + (HasTopLevel(b, "/") ? "(" + b + ")" : b);
}

std::string UnitDiv(const std::string& a, const std::string& b) {
  if (b == "1") return a;
  const std::string den = HasTopLevel(b, "*/") ? "(" + b + ")" : b;
  return a + "/" + den;
}

// A value with its unit in words (no unit when dimensionless).
std::string Quantity(double v, const std::string& unit) {
  return unit == "1" ? Number(v) : Number(v) + " " + unit;
}

// "x - 3.02 mm" or "x + 3.02 mm".
std::string Shifted(const std::string& x, double x0, const std::string& unit) {
  return x0 < 0.0 ? x + " + " + Quantity(-x0, unit) : x + " - " + Quantity(x0, unit);
}

struct Names {
  std::vector<std::string> taken;
  std::string operator()(std::string name) {
    while (std::find(taken.begin(), taken.end(), name) != taken.end()) name += "_fit";
    taken.push_back(name);
    return name;
  }
};

double WrapPhase(double phi) {
  phi = std::remainder(phi, 2.0 * kPi);  // [−π, π]
  if (phi <= -kPi) phi += 2.0 * kPi;
  return phi;
}

// The reported constants (header forms, x as is) and the offset from the internal fit.
bool Report(Kind kind, const Frame& frame, bool offset, const std::vector<double>& p,
            std::vector<double>& constants, double& reported_offset) {
  reported_offset = offset ? p.back() : 0.0;
  switch (kind) {
    case Kind::kLinear:
    case Kind::kQuadratic:
    case Kind::kCubic:
    case Kind::kProduct:
    case Kind::kScaledSquare:
    case Kind::kScaledAbs:
      constants = {p[0]};
      reported_offset = offset ? p[1] : 0.0;
      break;
    case Kind::kPower:
      constants = {p[0], p[1]};
      break;
    case Kind::kBump:
    case Kind::kStep:
    case Kind::kRamp:
      constants = {p[0], p[1], p[2]};
      break;
    case Kind::kSine: {
      double amp = p[0];
      double phase = p[2] - 2.0 * kPi * frame.centre / p[1];
      if (amp < 0.0) {
        amp = -amp;
        phase += kPi;
      }
      constants = {amp, p[1], WrapPhase(phase)};
      break;
    }
    case Kind::kExpRise: {
      const double a = p[0] * std::exp(frame.rise_shift / p[1]);
      constants = {a, p[1]};
      if (offset) reported_offset += p[0] - a;
      break;
    }
    case Kind::kExpDecay:
      constants = {p[0] * std::exp(frame.decay_shift / p[1]), p[1]};
      break;
  }
  return AllFinite(constants) && std::isfinite(reported_offset);
}

Formula Present(const FormSpec& spec, const std::vector<FormulaVariable>& vars,
                const std::string& target_unit, const std::vector<double>& v, double offset) {
  Formula f;
  f.form = spec.name;
  f.complexity = spec.complexity;
  for (const FormulaVariable& var : vars) f.variables.push_back(var.name);
  f.offset = offset;
  const std::string T = UnitOrOne(target_unit);
  const std::string& x = vars[0].name;
  const std::string X = UnitOrOne(vars[0].unit);
  const std::string y = vars.size() > 1 ? vars[1].name : "";
  const std::string Y = vars.size() > 1 ? UnitOrOne(vars[1].unit) : "1";
  Names names;
  for (const FormulaVariable& var : vars) names.taken.push_back(var.name);
  auto add = [&](const std::string& name, const std::string& unit, double value,
                 const std::string& doc) {
    f.constants.push_back({names(name), unit, value, doc});
    return f.constants.back().name;
  };
  switch (spec.kind) {
    case Kind::kLinear:
    case Kind::kQuadratic:
    case Kind::kCubic: {
      const int k = spec.kind == Kind::kLinear ? 1 : spec.kind == Kind::kQuadratic ? 2 : 3;
      const std::string unit = UnitDiv(T, k == 1 ? X : UnitPow(X, std::to_string(k)));
      const std::string c =
          add("c", unit, v[0], "coefficient of " + x + (k == 1 ? "" : "^" + std::to_string(k)));
      f.expression = c;
      for (int i = 0; i < k; ++i) f.expression += "*" + x;
      f.words = Quantity(v[0], unit) + " x " + x + (k == 1 ? "" : "^" + std::to_string(k));
      break;
    }
    case Kind::kPower: {
      const std::string unit = UnitDiv(T, UnitPow(X, Number(v[1])));
      const std::string c = add("c", unit, v[0], "coefficient of |" + x + "|^p");
      const std::string p = add("p", "1", v[1], "exponent of |" + x + "|");
      f.expression = c + "*abs(" + x + ")^" + p;
      f.words = Quantity(v[0], unit) + " x |" + x + "|^" + Number(v[1]);
      break;
    }
    case Kind::kBump: {
      const std::string a = add("amplitude", T, v[0], "height of the bump");
      const std::string x0 = add("x0", X, v[1], "centre of the bump along " + x);
      const std::string w = add("width", X, v[2], "1/e half-width of the bump along " + x);
      const std::string d = "((" + x + "-" + x0 + ")/" + w + ")";
      f.expression = a + "*exp(-" + d + "*" + d + ")";
      f.words = Quantity(v[0], T) + " x exp(-((" + Shifted(x, v[1], X) + ") / " +
                Quantity(v[2], X) + ")^2)";
      break;
    }
    case Kind::kSine: {
      const std::string a = add("amplitude", T, v[0], "amplitude of the sine");
      const std::string P = add("period", X, v[1], "period along " + x);
      const std::string phi = add("phase_rad", "rad", v[2], "phase at " + x + " = 0");
      f.expression = a + "*sin(2*pi*" + x + "/" + P + "+" + phi + ")";
      f.words = Quantity(v[0], T) + " x sin(2 pi " + x + " / " + Quantity(v[1], X) +
                (v[2] < 0.0 ? " - " + Number(-v[2]) : " + " + Number(v[2])) + " rad)";
      break;
    }
    case Kind::kStep: {
      const std::string a = add("amplitude", T, v[0], "height of the step");
      const std::string x0 = add("x0", X, v[1], "where along " + x + " the step is half done");
      const std::string w = add("width", X, v[2], "rise width of the step along " + x);
      f.expression = a + "/(1+exp(-(" + x + "-" + x0 + ")/" + w + "))";
      f.words = Quantity(v[0], T) + " / (1 + exp(-(" + Shifted(x, v[1], X) + ") / " +
                Quantity(v[2], X) + "))";
      break;
    }
    case Kind::kRamp: {
      const std::string unit = UnitDiv(T, X);
      const std::string a = add("slope", unit, v[0], "slope after the corner");
      const std::string x0 = add("x0", X, v[1], "where along " + x + " the ramp starts");
      const std::string w = add("width", X, v[2], "width of the corner along " + x);
      const std::string z = "(" + x + "-" + x0 + ")/" + w;
      f.expression = a + "*" + w + "*(max(" + z + ",0)+ln(1+exp(-abs(" + z + "))))";
      f.words = Quantity(v[0], unit) + " x " + Quantity(v[2], X) + " x ln(1 + exp((" +
                Shifted(x, v[1], X) + ") / " + Quantity(v[2], X) + "))";
      break;
    }
    case Kind::kExpRise:
    case Kind::kExpDecay: {
      const bool rise = spec.kind == Kind::kExpRise;
      const std::string a =
          add("amplitude", T, v[0], rise ? "level approached" : "value at " + x + " = 0");
      const std::string tau = add("tau", X, v[1], "length constant along " + x);
      const std::string e = "exp(-" + x + "/" + tau + ")";
      f.expression = rise ? a + "*(1-" + e + ")" : a + "*" + e;
      const std::string ew = "exp(-" + x + " / " + Quantity(v[1], X) + ")";
      f.words = Quantity(v[0], T) + (rise ? " x (1 - " + ew + ")" : " x " + ew);
      break;
    }
    case Kind::kProduct:
    case Kind::kScaledSquare:
    case Kind::kScaledAbs: {
      const std::string yu = spec.kind == Kind::kScaledSquare ? UnitPow(Y, "2") : Y;
      const std::string unit = UnitDiv(T, UnitMul(X, yu));
      const std::string yw = spec.kind == Kind::kProduct        ? y
                             : spec.kind == Kind::kScaledSquare ? y + "^2"
                                                                : "|" + y + "|";
      const std::string c = add("c", unit, v[0], "coefficient of " + x + " x " + yw);
      f.expression = c + "*" + x + "*" +
                     (spec.kind == Kind::kProduct        ? y
                      : spec.kind == Kind::kScaledSquare ? y + "*" + y
                                                         : "abs(" + y + ")");
      f.words = Quantity(v[0], unit) + " x " + x + " x " + yw;
      break;
    }
  }
  return f;
}

// Evaluates a form from its reported constants (header forms, x as is).
double EvaluateForm(Kind kind, const std::vector<FormulaConstant>& c, const double* in) {
  const double x = in[0];
  switch (kind) {
    case Kind::kLinear:
      return c[0].value * x;
    case Kind::kQuadratic:
      return c[0].value * x * x;
    case Kind::kCubic:
      return c[0].value * x * x * x;
    case Kind::kPower:
      return c[0].value * std::pow(std::abs(x), c[1].value);
    case Kind::kBump: {
      const double d = (x - c[1].value) / c[2].value;
      return c[0].value * std::exp(-d * d);
    }
    case Kind::kSine:
      return c[0].value * std::sin(2.0 * kPi * x / c[1].value + c[2].value);
    case Kind::kStep:
      return c[0].value / (1.0 + std::exp(-(x - c[1].value) / c[2].value));
    case Kind::kRamp:
      return c[0].value * c[2].value * Softplus((x - c[1].value) / c[2].value);
    case Kind::kExpRise:
      return c[0].value * (1.0 - std::exp(-x / c[1].value));
    case Kind::kExpDecay:
      return c[0].value * std::exp(-x / c[1].value);
    case Kind::kProduct:
      return c[0].value * x * in[1];
    case Kind::kScaledSquare:
      return c[0].value * x * in[1] * in[1];
    case Kind::kScaledAbs:
      return c[0].value * x * std::abs(in[1]);
  }
  return 0.0;
}

int ConstantCount(Kind k) {
  for (const FormSpec& f : kForms) {
    if (f.kind == k) return f.complexity;
  }
  return 0;
}

// ---------------------------------------------------------------------------------------

Data Check(const FormulaData& in) {
  if (in.variables.empty()) throw std::invalid_argument("FormulaData.variables: no variable");
  if (in.variables.size() > 2)
    throw std::invalid_argument("FormulaData.variables: " + std::to_string(in.variables.size()) +
                                " variables, at most 2");
  for (std::size_t v = 0; v < in.variables.size(); ++v) {
    if (in.variables[v].name.empty())
      throw std::invalid_argument("FormulaData.variables[" + std::to_string(v) + "].name: empty");
  }
  if (in.variables.size() == 2 && in.variables[0].name == in.variables[1].name)
    throw std::invalid_argument("FormulaData.variables: the same name twice");
  const std::size_t n = in.target.size();
  if (n == 0) throw std::invalid_argument("FormulaData.target: empty");
  if (in.inputs.size() != in.variables.size())
    throw std::invalid_argument("FormulaData.inputs: " + std::to_string(in.inputs.size()) +
                                " columns for " + std::to_string(in.variables.size()) +
                                " variables");
  for (std::size_t v = 0; v < in.inputs.size(); ++v) {
    if (in.inputs[v].size() != n)
      throw std::invalid_argument("FormulaData.inputs[" + std::to_string(v) +
                                  "]: " + std::to_string(in.inputs[v].size()) +
                                  " values, target has " + std::to_string(n));
  }
  if (!in.weight.empty() && in.weight.size() != n)
    throw std::invalid_argument("FormulaData.weight: " + std::to_string(in.weight.size()) +
                                " values, target has " + std::to_string(n));
  if (in.fold.size() != n)
    throw std::invalid_argument("FormulaData.fold: " + std::to_string(in.fold.size()) +
                                " values, target has " + std::to_string(n));
  Data d;
  d.n = n;
  d.variables = static_cast<int>(in.variables.size());
  d.offset = in.offset;
  d.x = in.inputs[0];
  if (d.variables > 1) d.y = in.inputs[1];
  d.t = in.target;
  d.sw.resize(n);
  double total = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(in.target[i]))
      throw std::invalid_argument("FormulaData.target[" + std::to_string(i) + "]: not finite");
    for (std::size_t v = 0; v < in.inputs.size(); ++v) {
      if (!std::isfinite(in.inputs[v][i]))
        throw std::invalid_argument("FormulaData.inputs[" + std::to_string(v) + "][" +
                                    std::to_string(i) + "]: not finite");
    }
    const double w = in.weight.empty() ? 1.0 : in.weight[i];
    if (!std::isfinite(w) || w < 0.0)
      throw std::invalid_argument("FormulaData.weight[" + std::to_string(i) +
                                  "]: negative or not finite");
    d.sw[i] = std::sqrt(w);
    total += w;
  }
  if (!(total > 0.0)) throw std::invalid_argument("FormulaData.weight: all zero");
  // The fits see the target in units of its spread (Ceres' absolute gradient tolerance, the
  // singularity thresholds): any unit fits alike.
  double mean = 0.0, spread = 0.0;
  for (std::size_t i = 0; i < n; ++i) mean += d.sw[i] * d.sw[i] * d.t[i];
  mean /= total;
  for (std::size_t i = 0; i < n; ++i)
    spread += d.sw[i] * d.sw[i] * (d.t[i] - mean) * (d.t[i] - mean);
  spread = std::sqrt(spread / total);
  d.scale = spread > 0.0 ? spread : (mean != 0.0 ? std::abs(mean) : 1.0);
  for (double& v : d.t) v /= d.scale;
  // Folds: the distinct non-negative values, renumbered; negative: never held out.
  std::vector<int> ids;
  for (const int f : in.fold) {
    if (f >= 0) ids.push_back(f);
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  if (ids.size() < 2)
    throw std::invalid_argument("FormulaData.fold: " + std::to_string(ids.size()) +
                                " fold(s), at least 2 needed");
  d.folds = static_cast<int>(ids.size());
  d.fold_index.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const int f = in.fold[i];
    d.fold_index[i] =
        f < 0 ? -1 : static_cast<int>(std::lower_bound(ids.begin(), ids.end(), f) - ids.begin());
  }
  d.all.resize(n);
  std::iota(d.all.begin(), d.all.end(), 0);
  // The subsample: every k-th sample of each fold, so that every fold keeps its share; the
  // coarse one likewise from the subsample.
  d.train.resize(static_cast<std::size_t>(d.folds));
  d.test.resize(static_cast<std::size_t>(d.folds));
  auto thin = [&](const std::vector<int>& from, std::size_t most) {
    const std::size_t stride = (from.size() + most - 1) / most;
    std::vector<std::size_t> seen(static_cast<std::size_t>(d.folds) + 1, 0);
    std::vector<int> out;
    for (const int i : from) {
      const auto slot = static_cast<std::size_t>(d.fold_index[static_cast<std::size_t>(i)] + 1);
      if (seen[slot]++ % stride == 0) out.push_back(i);
    }
    return out;
  };
  d.sub = thin(d.all, kMaxFitSamples);
  d.coarse = thin(d.sub, kMaxStartSamples);
  for (const int i : d.sub) {
    const int fi = d.fold_index[static_cast<std::size_t>(i)];
    for (int f = 0; f < d.folds; ++f)
      (f == fi ? d.test : d.train)[static_cast<std::size_t>(f)].push_back(i);
  }
  return d;
}

// Sorted by held-out error; exact ties go to the simpler form, then to the one that leaves
// less to the offset (exp_rise and exp_decay with an offset, see SearchFormulas).
// (A NaN error, only possible in a caller's own list, counts as +inf.)
double ErrorKey(const Formula& f) { return std::isnan(f.held_out_mse) ? kInf : f.held_out_mse; }

void SortFormulas(std::vector<Formula>& f) {
  std::stable_sort(f.begin(), f.end(),
                   [](const Formula& a, const Formula& b) { return ErrorKey(a) < ErrorKey(b); });
  std::size_t begin = 0;
  while (begin < f.size()) {
    std::size_t end = begin + 1;
    const double h = f[begin].held_out_mse;
    while (end < f.size() && std::isfinite(h) && f[end].held_out_mse == h) ++end;
    std::stable_sort(f.begin() + static_cast<std::ptrdiff_t>(begin),
                     f.begin() + static_cast<std::ptrdiff_t>(end),
                     [](const Formula& a, const Formula& b) {
                       if (a.complexity != b.complexity) return a.complexity < b.complexity;
                       return std::abs(a.offset) < std::abs(b.offset);
                     });
    begin = end;
  }
}

}  // namespace formula_search_impl
}  // namespace

double Formula::Evaluate(const double* inputs) const {
  namespace impl = formula_search_impl;
  const impl::FormSpec* spec = impl::FindForm(form);
  if (spec == nullptr)
    throw std::invalid_argument("Formula::Evaluate: unknown form '" + form + "'");
  if (static_cast<int>(constants.size()) != impl::ConstantCount(spec->kind))
    throw std::invalid_argument("Formula::Evaluate: form '" + form + "' has " +
                                std::to_string(impl::ConstantCount(spec->kind)) +
                                " constants, not " + std::to_string(constants.size()));
  return impl::EvaluateForm(spec->kind, constants, inputs);
}

std::vector<Formula> SearchFormulas(const FormulaData& data, const FormulaSearchOptions& options) {
  namespace impl = formula_search_impl;
  const impl::Data d = impl::Check(data);
  if (options.starts < 1)
    throw std::invalid_argument("FormulaSearchOptions.starts: " + std::to_string(options.starts) +
                                ", at least 1");
  std::vector<const impl::FormSpec*> forms;
  if (options.forms.empty()) {
    for (const impl::FormSpec& f : impl::kForms) {
      if (f.variables == d.variables) forms.push_back(&f);
    }
  } else {
    for (const std::string& name : options.forms) {
      const impl::FormSpec* f = impl::FindForm(name);
      if (f == nullptr)
        throw std::invalid_argument("FormulaSearchOptions.forms: unknown form '" + name + "'");
      if (f->variables != d.variables)
        throw std::invalid_argument("FormulaSearchOptions.forms: '" + name + "' takes " +
                                    std::to_string(f->variables) + " variable(s), the data has " +
                                    std::to_string(d.variables));
      if (std::find(forms.begin(), forms.end(), f) == forms.end()) forms.push_back(f);
    }
  }
  const impl::Axis axis = impl::Describe(d.x, d.sub);
  // Each form fitted and scored (nonlinear ones on the subsample).
  struct Candidate {
    const impl::FormSpec* spec;
    impl::Curve curve;
    impl::FitOutcome fit;
  };
  std::vector<Candidate> candidates;
  for (const impl::FormSpec* spec : forms) {
    Candidate k{spec, {}, {}};
    if (impl::IsLinearForm(spec->kind)) {
      k.fit = impl::FitLinear(d, spec->kind);
    } else {
      impl::Curve& c = k.curve;
      c.kind = spec->kind;
      c.offset = d.offset;
      c.size = spec->complexity + (d.offset ? 1 : 0);
      c.x = d.x.data();
      c.t = d.t.data();
      c.sw = d.sw.data();
      c.frame.centre = 0.5 * (axis.min + axis.max);
      c.frame.decay_shift = axis.min;
      c.frame.rise_shift = d.offset ? axis.min : 0.0;
      impl::SetBounds(c, axis);
      k.fit = impl::FitNonlinear(d, c, axis, options.starts);
    }
    candidates.push_back(std::move(k));
  }
  // With an offset exp_rise and exp_decay are one family (a·(1 − e) + o = −a·e + (a + o)):
  // both get the better of their two fits, so that they tie exactly and the one that leaves
  // less to the offset sorts first.
  Candidate* rise = nullptr;
  Candidate* decay = nullptr;
  for (Candidate& k : candidates) {
    if (k.spec->kind == impl::Kind::kExpRise) rise = &k;
    if (k.spec->kind == impl::Kind::kExpDecay) decay = &k;
  }
  if (d.offset && rise != nullptr && decay != nullptr && (rise->fit.ok || decay->fit.ok)) {
    const bool from_rise =
        rise->fit.ok && (!decay->fit.ok || rise->fit.held_out_mse <= decay->fit.held_out_mse);
    const Candidate& from = from_rise ? *rise : *decay;
    Candidate& to = from_rise ? *decay : *rise;
    to.fit = from.fit;
    // p = {amplitude, τ, offset}, both anchored at the smallest input.
    to.fit.p[0] = -from.fit.p[0];
    to.fit.p[2] = from.fit.p[2] + from.fit.p[0];
  }
  auto present = [&](Candidate& k) {
    std::vector<double> constants;
    double offset = 0.0;
    std::vector<double> p = k.fit.p;  // back to the target's unit
    if (!p.empty()) {
      p[0] *= d.scale;
      if (d.offset || impl::IsLinearForm(k.spec->kind)) p.back() *= d.scale;
    }
    if (k.fit.ok && !impl::Report(k.spec->kind, k.curve.frame, d.offset, p, constants, offset))
      k.fit.ok = false;
    if (!k.fit.ok) {
      constants.assign(static_cast<std::size_t>(k.spec->complexity), 0.0);
      offset = 0.0;
    }
    Formula f = impl::Present(*k.spec, data.variables, data.target_unit, constants, offset);
    if (k.fit.ok) {
      f.mse = k.fit.mse * d.scale * d.scale;
      f.held_out_mse = k.fit.held_out_mse * d.scale * d.scale;
    } else {
      f.mse = f.held_out_mse = impl::kInf;
      f.words = "(fit failed) " + f.words;
    }
    return f;
  };
  std::vector<Formula> out;
  for (Candidate& k : candidates) out.push_back(present(k));
  // The Pareto front's nonlinear forms refitted on every sample (the others keep their
  // subsample constants: refitting all on 50 000 samples would cost most of the time).
  if (d.sub.size() < d.n) {
    for (const Formula& f : ParetoFront(out)) {
      for (std::size_t i = 0; i < candidates.size(); ++i) {
        Candidate& k = candidates[i];
        if (f.form != k.spec->name || impl::IsLinearForm(k.spec->kind)) continue;
        impl::Refit(d, k.curve, k.fit);
        out[i] = present(k);
      }
    }
  }
  impl::SortFormulas(out);
  return out;
}

std::vector<Formula> ParetoFront(const std::vector<Formula>& formulas) {
  namespace impl = formula_search_impl;
  // The best of each complexity in SearchFormulas' order (exact ties included), then kept
  // while the held-out error falls.
  std::vector<Formula> sorted = formulas;
  impl::SortFormulas(sorted);
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const Formula& a, const Formula& b) { return a.complexity < b.complexity; });
  std::vector<Formula> front;
  double best = impl::kInf;
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    if (i > 0 && sorted[i].complexity == sorted[i - 1].complexity) continue;
    if (sorted[i].held_out_mse < best) {
      best = sorted[i].held_out_mse;
      front.push_back(sorted[i]);
    }
  }
  return front;
}

}  // namespace echoservo::lab
