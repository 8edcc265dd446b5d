#include "lab/smooth_shape.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace echoservo::lab {
namespace {

// The two hat functions that are non-zero at x: lower knot index and the upper's weight.
struct Hat {
  std::size_t k = 0;
  double t = 0.0;  // weight of knot k+1; knot k gets 1 − t
};

Hat LocateHat(const std::vector<double>& knots, double x) {
  const std::size_t n = knots.size();
  if (n < 2 || !(x > knots.front())) return {0, 0.0};
  if (x >= knots.back()) return {n - 2, 1.0};
  const auto it = std::upper_bound(knots.begin(), knots.end(), x);
  const auto k = static_cast<std::size_t>(it - knots.begin()) - 1;
  return {k, (x - knots[k]) / (knots[k + 1] - knots[k])};
}

// Up to four (column, weight) pairs of one sample's row of the shape's basis.
struct BasisEntries {
  std::size_t column[4];
  double weight[4];
  int count = 0;
};

BasisEntries BasisRow(const std::vector<ShapeAxis>& axes, const double* x) {
  BasisEntries row;
  if (axes.size() == 1) {
    const Hat h = LocateHat(axes[0].knots, x[0]);
    if (axes[0].knots.size() == 1) {
      row.column[0] = 0;
      row.weight[0] = 1.0;
      row.count = 1;
      return row;
    }
    row.column[0] = h.k;
    row.weight[0] = 1.0 - h.t;
    row.column[1] = h.k + 1;
    row.weight[1] = h.t;
    row.count = 2;
    return row;
  }
  const std::size_t n1 = axes[1].knots.size();
  const Hat a = LocateHat(axes[0].knots, x[0]);
  const Hat b = LocateHat(axes[1].knots, x[1]);
  const std::size_t a_hi = axes[0].knots.size() > 1 ? a.k + 1 : a.k;
  const std::size_t b_hi = n1 > 1 ? b.k + 1 : b.k;
  const double wa[2] = {1.0 - a.t, a.t};
  const double wb[2] = {1.0 - b.t, b.t};
  const std::size_t ia[2] = {a.k, a_hi};
  const std::size_t ib[2] = {b.k, b_hi};
  for (int p = 0; p < 2; ++p) {
    for (int q = 0; q < 2; ++q) {
      row.column[row.count] = ia[p] * n1 + ib[q];
      row.weight[row.count] = wa[p] * wb[q];
      ++row.count;
    }
  }
  return row;
}

// Σ (second differences along each axis)² as a quadratic form over the knot values.
Eigen::MatrixXd PenaltyMatrix(const std::vector<ShapeAxis>& axes) {
  const std::size_t n0 = axes[0].knots.size();
  const std::size_t n1 = axes.size() > 1 ? axes[1].knots.size() : 1;
  const auto k = static_cast<Eigen::Index>(n0 * n1);
  Eigen::MatrixXd p = Eigen::MatrixXd::Zero(k, k);
  auto add = [&](std::size_t a, std::size_t b, std::size_t c) {
    const Eigen::Index idx[3] = {static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b),
                                 static_cast<Eigen::Index>(c)};
    const double coef[3] = {1.0, -2.0, 1.0};
    for (int r = 0; r < 3; ++r)
      for (int s = 0; s < 3; ++s) p(idx[r], idx[s]) += coef[r] * coef[s];
  };
  for (std::size_t j = 0; j < n1; ++j)
    for (std::size_t i = 1; i + 1 < n0; ++i) add((i - 1) * n1 + j, i * n1 + j, (i + 1) * n1 + j);
  for (std::size_t i = 0; i < n0; ++i)
    for (std::size_t j = 1; j + 1 < n1; ++j) add(i * n1 + j - 1, i * n1 + j, i * n1 + j + 1);
  return p;
}

void CheckShapeInput(const std::vector<ShapeAxis>& axes, const ShapeSamples& s) {
  if (axes.empty() || axes.size() > 2)
    throw std::invalid_argument("smooth shape: 1 or 2 axes, not " + std::to_string(axes.size()));
  for (const ShapeAxis& a : axes) {
    if (a.knots.empty())
      throw std::invalid_argument("smooth shape: axis " + a.variable + " has no knot");
    for (std::size_t k = 1; k < a.knots.size(); ++k) {
      if (!(a.knots[k] > a.knots[k - 1]))
        throw std::invalid_argument("smooth shape: knots of " + a.variable +
                                    " are not strictly increasing at index " + std::to_string(k));
    }
  }
  const std::size_t n = s.target.size();
  if (s.inputs.size() != axes.size())
    throw std::invalid_argument("smooth shape: one input per axis needed");
  for (const auto& in : s.inputs)
    if (in.size() != n) throw std::invalid_argument("smooth shape: an input's length differs");
  auto optional = [&](std::size_t size, const char* what) {
    if (size != 0 && size != n)
      throw std::invalid_argument(std::string("smooth shape: ") + what + "'s length differs");
  };
  optional(s.multiplier.size(), "multiplier");
  optional(s.weight.size(), "weight");
  optional(s.group.size(), "group");
  for (const auto& c : s.nuisance) optional(c.empty() ? n : c.size(), "a nuisance column");
  if (s.fold.size() != n) throw std::invalid_argument("smooth shape: fold's length differs");
  const int folds = n == 0 ? 0 : *std::max_element(s.fold.begin(), s.fold.end()) + 1;
  if (folds < 2) throw std::invalid_argument("smooth shape: at least 2 folds are needed");
}

}  // namespace

int ShapeBasis(const std::vector<ShapeAxis>& axes, const double* inputs, std::size_t* columns,
               double* weights) {
  const BasisEntries row = BasisRow(axes, inputs);
  for (int c = 0; c < row.count; ++c) {
    columns[c] = row.column[c];
    weights[c] = row.weight[c];
  }
  return row.count;
}

double SmoothShape::Evaluate(double x) const { return Evaluate(&x); }

double SmoothShape::Evaluate(double x, double y) const {
  const double in[2] = {x, y};
  return Evaluate(in);
}

double SmoothShape::Evaluate(const double* inputs) const {
  if (axes.empty() || values.empty()) return 0.0;
  const BasisEntries row = BasisRow(axes, inputs);
  double v = 0.0;
  for (int c = 0; c < row.count; ++c) v += row.weight[c] * values[row.column[c]];
  return v;
}

std::vector<double> QuantileKnots(const std::vector<double>& x, int count) {
  std::vector<double> sorted;
  sorted.reserve(x.size());
  for (double v : x)
    if (std::isfinite(v)) sorted.push_back(v);
  std::sort(sorted.begin(), sorted.end());
  std::vector<double> distinct = sorted;
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  if (count < 2 || distinct.size() <= static_cast<std::size_t>(count)) {
    if (count < 2 && !distinct.empty()) return {distinct.front(), distinct.back()};
    return distinct;
  }
  std::vector<double> knots;
  const auto n = static_cast<double>(sorted.size() - 1);
  for (int k = 0; k < count; ++k) {
    const double q = sorted[static_cast<std::size_t>(std::lround(n * k / (count - 1)))];
    if (knots.empty() || q > knots.back()) knots.push_back(q);
  }
  if (knots.back() < sorted.back()) knots.push_back(sorted.back());
  return knots;
}

SmoothShape FitSmoothShape(const std::vector<ShapeAxis>& axes, const ShapeSamples& s,
                           const ShapeFitOptions& o) {
  CheckShapeInput(axes, s);
  const std::size_t n = s.target.size();
  const std::size_t k_shape =
      axes[0].knots.size() * (axes.size() > 1 ? axes[1].knots.size() : std::size_t{1});
  std::size_t groups = 0;
  for (std::size_t g : s.group) groups = std::max(groups, g + 1);
  const std::size_t j = s.nuisance.size();
  const std::size_t dim = k_shape + j + groups;
  const int folds = *std::max_element(s.fold.begin(), s.fold.end()) + 1;
  const auto d = static_cast<Eigen::Index>(dim);

  // Normal equations per fold (fold −1 only enters the final fit).
  std::vector<Eigen::MatrixXd> a(static_cast<std::size_t>(folds) + 1, Eigen::MatrixXd::Zero(d, d));
  std::vector<Eigen::VectorXd> b(a.size(), Eigen::VectorXd::Zero(d));
  std::vector<double> weight_of(a.size(), 0.0);
  std::vector<BasisEntries> rows(n);
  std::vector<std::size_t> cols;
  std::vector<double> vals;
  double total_weight = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    double x[2] = {s.inputs[0][i], axes.size() > 1 ? s.inputs[1][i] : 0.0};
    rows[i] = BasisRow(axes, x);
    const double m = s.multiplier.empty() ? 1.0 : s.multiplier[i];
    const double w = s.weight.empty() ? 1.0 : s.weight[i];
    if (!(w > 0.0) || !std::isfinite(s.target[i])) continue;
    cols.clear();
    vals.clear();
    for (int c = 0; c < rows[i].count; ++c) {
      cols.push_back(rows[i].column[c]);
      vals.push_back(rows[i].weight[c] * m);
    }
    for (std::size_t c = 0; c < j; ++c) {
      if (s.nuisance[c].empty()) continue;
      cols.push_back(k_shape + c);
      vals.push_back(s.nuisance[c][i]);
    }
    if (!s.group.empty()) {
      cols.push_back(k_shape + j + s.group[i]);
      vals.push_back(1.0);
    }
    const std::size_t f =
        s.fold[i] < 0 ? static_cast<std::size_t>(folds) : static_cast<std::size_t>(s.fold[i]);
    Eigen::MatrixXd& af = a[f];
    Eigen::VectorXd& bf = b[f];
    for (std::size_t p = 0; p < cols.size(); ++p) {
      const auto cp = static_cast<Eigen::Index>(cols[p]);
      bf(cp) += w * vals[p] * s.target[i];
      for (std::size_t q = 0; q < cols.size(); ++q)
        af(cp, static_cast<Eigen::Index>(cols[q])) += w * vals[p] * vals[q];
    }
    weight_of[f] += w;
    total_weight += w;
  }
  Eigen::MatrixXd a_all = Eigen::MatrixXd::Zero(d, d);
  Eigen::VectorXd b_all = Eigen::VectorXd::Zero(d);
  for (std::size_t f = 0; f < a.size(); ++f) {
    a_all += a[f];
    b_all += b[f];
  }
  Eigen::MatrixXd penalty = Eigen::MatrixXd::Zero(d, d);
  const auto ks = static_cast<Eigen::Index>(k_shape);
  penalty.topLeftCorner(ks, ks) = PenaltyMatrix(axes);
  // A tiny ridge keeps knots without data, unseen groups and collinear nuisance defined.
  const double ridge = 1e-9 * std::max(1.0, a_all.diagonal().maxCoeff());

  auto solve = [&](const Eigen::MatrixXd& am, const Eigen::VectorXd& bm, double lambda) {
    Eigen::MatrixXd m = am + lambda * penalty;
    m.diagonal().array() += ridge;
    return Eigen::VectorXd(m.ldlt().solve(bm));
  };
  // Residual of sample i under coefficients beta, with the groups' constants re-estimated
  // on the scored samples themselves (as the lab refits a held-out trial's offset).
  auto predict = [&](const Eigen::VectorXd& beta, std::size_t i, bool with_groups,
                     bool with_nuisance) {
    double v = 0.0;
    const double m = s.multiplier.empty() ? 1.0 : s.multiplier[i];
    for (int c = 0; c < rows[i].count; ++c)
      v += rows[i].weight[c] * m * beta(static_cast<Eigen::Index>(rows[i].column[c]));
    for (std::size_t c = 0; with_nuisance && c < j; ++c)
      if (!s.nuisance[c].empty())
        v += s.nuisance[c][i] * beta(static_cast<Eigen::Index>(k_shape + c));
    if (with_groups && !s.group.empty())
      v += beta(static_cast<Eigen::Index>(k_shape + j + s.group[i]));
    return v;
  };
  // Mean squares of the target and of target − shape over the samples of `fold` (−2: all),
  // each with what the nuisance absorbs re-estimated on those samples themselves: the
  // groups' weighted means removed, then the nuisance columns regressed out (as the lab
  // refits a held-out trial's offset, and as Coulomb and viscous friction refit with a term).
  auto scores = [&](const Eigen::VectorXd* beta, int fold) {
    std::vector<std::size_t> idx;
    for (std::size_t i = 0; i < n; ++i) {
      const double w = s.weight.empty() ? 1.0 : s.weight[i];
      if (w > 0.0 && std::isfinite(s.target[i]) && (fold == -2 || s.fold[i] == fold))
        idx.push_back(i);
    }
    const auto m = static_cast<Eigen::Index>(idx.size());
    std::size_t used_columns = 0;
    for (const auto& c : s.nuisance) used_columns += c.empty() ? 0 : 1;
    // Columns: target, target − shape, then the nuisance columns.
    Eigen::MatrixXd x(m, static_cast<Eigen::Index>(2 + used_columns));
    Eigen::VectorXd w(m);
    for (Eigen::Index r = 0; r < m; ++r) {
      const std::size_t i = idx[static_cast<std::size_t>(r)];
      w(r) = s.weight.empty() ? 1.0 : s.weight[i];
      x(r, 0) = s.target[i];
      x(r, 1) = s.target[i] - (beta != nullptr ? predict(*beta, i, false, false) : 0.0);
      Eigen::Index c = 2;
      for (const auto& col : s.nuisance)
        if (!col.empty()) x(r, c++) = col[i];
    }
    if (!s.group.empty()) {
      std::vector<double> sw(groups, 0.0);
      Eigen::MatrixXd sums = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(groups), x.cols());
      for (Eigen::Index r = 0; r < m; ++r) {
        const auto g = s.group[idx[static_cast<std::size_t>(r)]];
        sw[g] += w(r);
        sums.row(static_cast<Eigen::Index>(g)) += w(r) * x.row(r);
      }
      for (Eigen::Index r = 0; r < m; ++r) {
        const auto g = s.group[idx[static_cast<std::size_t>(r)]];
        x.row(r) -= sums.row(static_cast<Eigen::Index>(g)) / sw[g];
      }
    }
    if (used_columns > 0 && m > 0) {
      const auto j0 = static_cast<Eigen::Index>(used_columns);
      const Eigen::MatrixXd nz = x.rightCols(j0);
      Eigen::MatrixXd gram = nz.transpose() * w.asDiagonal() * nz;
      gram.diagonal().array() += 1e-12 * std::max(1.0, gram.diagonal().maxCoeff());
      const Eigen::MatrixXd coef =
          gram.ldlt().solve(nz.transpose() * w.asDiagonal() * x.leftCols(2));
      x.leftCols(2) -= nz * coef;
    }
    const double wsum = w.sum();
    if (!(wsum > 0.0)) return std::pair<double, double>{0.0, 0.0};
    const double before = (w.array() * x.col(0).array().square()).sum() / wsum;
    const double after = (w.array() * x.col(1).array().square()).sum() / wsum;
    return std::pair<double, double>{before, after};
  };

  const double scale = o.scale_lambda_by_weight ? total_weight : 1.0;
  SmoothShape best;
  best.axes = axes;
  double best_after = std::numeric_limits<double>::infinity();
  double best_before = 0.0;
  for (double lambda : o.lambdas) {
    double before = 0.0, after = 0.0, wsum = 0.0;
    for (int f = 0; f < folds; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      const Eigen::VectorXd beta = solve(a_all - a[fi], b_all - b[fi], lambda * scale);
      const auto [yb, ya] = scores(&beta, f);
      before += weight_of[fi] * yb;
      after += weight_of[fi] * ya;
      wsum += weight_of[fi];
    }
    if (wsum <= 0.0) continue;
    if (after / wsum < best_after) {
      best_after = after / wsum;
      best_before = before / wsum;
      best.lambda = lambda;
    }
  }
  best.held_out_mse = best_after;
  best.held_out_gain = best_before - best_after;
  const Eigen::VectorXd beta = solve(a_all, b_all, best.lambda * scale);
  best.values.assign(beta.data(), beta.data() + k_shape);
  const auto [all_before, all_after] = scores(&beta, -2);
  best.in_sample_gain = all_before - all_after;
  return best;
}

}  // namespace echoservo::lab
