#include "estimation/ar_reference.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace echoservo::estimation {
namespace {

constexpr double kBrokenInterval = 1.6;  // × the median interval: the lags' delays break
constexpr std::size_t kMinTrainingRows = 20;

std::string Seconds(double s) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.1f s", s);
  return buffer;
}

// run_start[j]: the first sample of the regular run holding sample j.
std::vector<std::size_t> RunStarts(const MotionTrace& m, double dt) {
  std::vector<std::size_t> start(m.size(), 0);
  for (std::size_t j = 1; j < m.size(); ++j) {
    const double step = m.t_s[j] - m.t_s[j - 1];
    start[j] = step > kBrokenInterval * dt ? j : start[j - 1];
  }
  return start;
}

struct Rows {
  int width = 0;               // parameters of the largest order
  std::vector<std::size_t> n;  // sample index of each row
  std::vector<double> u;       // width values per row
  std::vector<double> y;       // target − x_n
  const double* Row(std::size_t r) const { return u.data() + r * static_cast<std::size_t>(width); }
};

void Regressors(const MotionTrace& m, std::size_t n, int p, int stride, double* u) {
  u[0] = 1.0;
  for (int i = 1; i < p; ++i)
    u[i] = m.position_mm[n - static_cast<std::size_t>(i * stride)] - m.position_mm[n];
}

bool HistoryOk(const std::vector<std::size_t>& start, std::size_t n, int p, int stride) {
  const std::size_t reach = static_cast<std::size_t>((p - 1) * stride);
  return n >= reach && n - reach >= start[n];
}

using Matrix = Eigen::MatrixXd;
using Vector = Eigen::VectorXd;

void Accumulate(const Rows& rows, std::size_t r, Matrix& g, Vector& b) {
  const Eigen::Map<const Vector> u(rows.Row(r), rows.width);
  g.selfadjointView<Eigen::Lower>().rankUpdate(u);
  b += u * rows.y[r];
}

Vector Solve(const Matrix& g_lower, const Vector& b, int p) {
  Matrix g = g_lower.topLeftCorner(p, p).selfadjointView<Eigen::Lower>();
  const double ridge = kArRidge * std::max(g.diagonal().mean(), 1e-12);
  g.diagonal().array() += ridge;
  return g.ldlt().solve(b.head(p));
}

}  // namespace

double ArReferenceMinimumSpan(const ArReferenceOptions& o, double rate_hz) {
  const double rows_s = static_cast<double>(kMinTrainingRows) / std::max(rate_hz, 1e-9);
  return 2.0 * (std::max(o.min_half_s, rows_s) + o.latency_s);
}

ArReference FitArReference(const MotionTrace& m, const ArReferenceOptions& o) {
  if (!(std::isfinite(o.latency_s) && o.latency_s >= 0.0 && o.max_history_s > 0.0 &&
        o.max_lag_rate_hz > 0.0 && o.min_half_s > 0.0 && o.folds >= 2)) {
    throw std::invalid_argument(
        "autoregressive reference: latency >= 0, history, lag rate and half span > 0, "
        "folds >= 2");
  }
  ValidateMotionTrace(m);
  const double dt = MedianInterval(m);
  const double rate = 1.0 / dt;
  const double needed = ArReferenceMinimumSpan(o, rate);
  const std::string too_short =
      m.source + ": the trace spans " + Seconds(m.duration_s()) +
      "; the autoregressive reference needs at least " + Seconds(needed) +
      " (fitted on the first half, scored on the second; each half at least " +
      Seconds(needed / 2.0) + ")";
  if (m.duration_s() < needed) throw std::invalid_argument(too_short);

  ArReference ref;
  ref.stride = std::max(1, static_cast<int>(std::ceil(rate / o.max_lag_rate_hz - 1e-9)));
  ref.split_s = 0.5 * (m.t_s.front() + m.t_s.back());
  const auto first_half = static_cast<std::size_t>(
      std::lower_bound(m.t_s.begin(), m.t_s.end(), ref.split_s) - m.t_s.begin());
  const int by_history =
      1 + static_cast<int>(std::floor(o.max_history_s * rate / ref.stride + 1e-9));
  const int by_rows = static_cast<int>(first_half / kArRowsPerParameter);
  for (int p : kArCandidateOrders)
    if (p <= by_history && p <= std::max(by_rows, 1)) ref.candidates.push_back(p);
  // Training rows: the full history of the largest order, the target at or before t_mid.
  // A trace with many gaps has few rows with a long history: the largest orders are dropped
  // until the rows suffice.
  const std::vector<std::size_t> start = RunStarts(m, dt);
  const TraceInterpolator at(m);
  const std::size_t needed_rows =
      std::max<std::size_t>(kMinTrainingRows, 2 * static_cast<std::size_t>(o.folds));
  Rows rows;
  std::vector<double> u;
  while (true) {
    const int width = ref.candidates.back();
    rows = Rows{};
    rows.width = width;
    u.assign(static_cast<std::size_t>(width), 0.0);
    for (std::size_t n = 0; n < first_half; ++n) {
      const double target_t = m.t_s[n] + o.latency_s;
      double target = 0.0;
      if (target_t > ref.split_s || !HistoryOk(start, n, width, ref.stride) ||
          !at.At(target_t, target))
        continue;
      Regressors(m, n, width, ref.stride, u.data());
      rows.n.push_back(n);
      rows.u.insert(rows.u.end(), u.begin(), u.end());
      rows.y.push_back(target - m.position_mm[n]);
    }
    const bool enough = rows.y.size() >= needed_rows &&
                        rows.y.size() >= static_cast<std::size_t>(kArRowsPerParameter * width);
    if (enough || ref.candidates.size() == 1) break;
    ref.candidates.pop_back();
  }
  const int width = rows.width;
  const std::size_t count = rows.y.size();
  if (count < needed_rows)
    throw std::invalid_argument(m.source + ": only " + std::to_string(count) +
                                " gap-free training rows in the first half of the trace; the "
                                "autoregressive reference needs " +
                                std::to_string(needed_rows) + " (fewer or shorter gaps)");
  ref.trained = count;

  // Blocked cross-validation: fold f holds out rows [lo, hi) and leaves out of its training
  // every row whose lags or target reach into the held-out samples.
  Matrix g_all = Matrix::Zero(width, width);
  Vector b_all = Vector::Zero(width);
  for (std::size_t r = 0; r < count; ++r) Accumulate(rows, r, g_all, b_all);
  const std::size_t reach = static_cast<std::size_t>((width - 1) * ref.stride) +
                            static_cast<std::size_t>(std::ceil(o.latency_s * rate)) + 1;
  std::vector<double> sse(ref.candidates.size(), 0.0);
  const auto folds = static_cast<std::size_t>(o.folds);
  for (std::size_t f = 0; f < folds; ++f) {
    const std::size_t lo = f * count / folds;
    const std::size_t hi = (f + 1) * count / folds;
    const std::size_t n_lo = rows.n[lo] > reach ? rows.n[lo] - reach : 0;
    const std::size_t n_hi = rows.n[hi - 1] + reach;
    Matrix g = g_all;
    Vector b = b_all;
    for (std::size_t r = 0; r < count; ++r) {
      if (rows.n[r] < n_lo || rows.n[r] > n_hi) continue;
      const Eigen::Map<const Vector> ur(rows.Row(r), width);
      g.selfadjointView<Eigen::Lower>().rankUpdate(ur, -1.0);
      b -= ur * rows.y[r];
    }
    for (std::size_t c = 0; c < ref.candidates.size(); ++c) {
      const int p = ref.candidates[c];
      const Vector w = Solve(g, b, p);
      for (std::size_t r = lo; r < hi; ++r) {
        const Eigen::Map<const Vector> ur(rows.Row(r), p);
        const double e = rows.y[r] - w.dot(ur);
        sse[c] += e * e;
      }
    }
  }
  std::size_t best = 0;
  for (std::size_t c = 0; c < sse.size(); ++c) {
    ref.validation_rms_mm.push_back(std::sqrt(sse[c] / static_cast<double>(count)));
    if (sse[c] < sse[best]) best = c;
  }
  ref.order = ref.candidates[best];
  ref.history_s = static_cast<double>((ref.order - 1) * ref.stride) * dt;
  const Vector w = Solve(g_all, b_all, ref.order);
  ref.weights.assign(w.data(), w.data() + w.size());

  // The second half: predict at every measurement; hold where a gap broke the history.
  for (std::size_t n = first_half; n < m.size(); ++n) {
    double predicted = m.position_mm[n];
    if (HistoryOk(start, n, ref.order, ref.stride)) {
      Regressors(m, n, ref.order, ref.stride, u.data());
      predicted += w.dot(Eigen::Map<const Vector>(u.data(), ref.order));
    } else {
      ++ref.held;
    }
    ref.t_s.push_back(m.t_s[n]);
    ref.predicted_mm.push_back(predicted);
  }
  ref.scored = ref.t_s.size();
  return ref;
}

}  // namespace echoservo::estimation
