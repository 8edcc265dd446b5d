// An adaptive direct-horizon autoregressive predictor: least squares with forgetting on the
// newest lags, predicting the position `horizon_s` ahead directly (not by iterating a
// one-step model), its order chosen online by each candidate's out-of-sample error — the
// causal counterpart of the offline reference (estimation/ar_reference.h), with the same
// model and the same candidate orders.
//
// In: positions (mm) stamped at acquisition (s, strictly increasing), at a roughly constant
// rate (learned from the first intervals). Model, on the sample index n, lags `stride`
// samples apart (lags at ≤ max_lag_rate_hz): x(t_n + horizon) − x_n = w₀ + Σ_{i=1..p−1}
// wᵢ (x_{n−i·stride} − x_n) (offset-free: a breathing baseline needs no refit; w = 0 is the
// zero-order hold), the target the samples linearly interpolated at t_n + horizon. Each
// sample completes one training row: the Gram matrix of the largest order is accumulated
// with forgetting λ = 1 − 1/(memory_s × rate); every refit_s the candidate orders (1, 2, 3,
// 4, 6, 8, 11, 16, 22, 32, 45, 64, 90, up to max_history_s of lags) are solved (ridge), and
// each row first scores every candidate a priori (its error before it learns the row,
// averaged over validation_s): the best candidate with ≥ 10 rows per parameter and ≥ 10
// scored rows predicts. Out: Predict(t) in mm; between the newest measurement and the horizon it
// interpolates linearly, past it it holds. Bounded: the prediction is clamped to the recent
// range ± a margin. Falls back to the zero-order hold until a candidate is eligible, after
// an irregular interval or a gap (history reset, learning kept; 1–3 dropped samples on the
// grid are filled by linear interpolation instead); a candidate whose solution is
// ill-conditioned (Σ|w| > max_weight_sum) sits out until a refit solves it well. Not robustified:
// clipping the a-priori error (tried at 3 and 6 σ) cost 5–35 % on the real phantom's nearly
// deterministic motion, whose a-priori errors are heavy-tailed by nature, and gained nothing
// measurable on traces with outliers (docs/predictor.md); the competition's other members cover
// outliers. Errors: the constructor throws std::invalid_argument for bad options; Update throws it
// for a non-finite input or a time not after the previous one.
// Details: docs/predictor.md#the-least-squares-autoregressive-predictor-estimationls_ar_predictorh
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "estimation/ar_reference.h"
#include "estimation/motion_predictor.h"
#include "estimation/sample_grid.h"

namespace echoservo::estimation {

struct LsArPredictorOptions {
  double horizon_s = 0.1;         // how far ahead it predicts (the imaging latency)
  double max_history_s = 2.0;     // the longest lag span of a candidate order
  double max_lag_rate_hz = 50.0;  // lags no denser than this (stride)
  double memory_s = 60.0;         // forgetting λ = 1 − 1/(memory_s × rate)
  double validation_s = 10.0;     // memory of each candidate's a-priori error
  double refit_s = 0.5;           // the candidates are solved this often
  double ridge = kArRidge;        // × the Gram's mean diagonal, added to it
  double margin_fraction = 0.25;  // clamp to [min − m, max + m], m = fraction × range
  double range_window_s = 3.0;    // the "recent" range for the clamp
  double max_weight_sum = 50.0;   // Σ|w| beyond this: ill-conditioned, reset
};

class LsArPredictor final : public MotionPredictor {
 public:
  static constexpr int kMaxParams = 90;
  using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxParams, 1>;
  using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxParams, kMaxParams>;

  // Throws std::invalid_argument for inconsistent options.
  explicit LsArPredictor(LsArPredictorOptions options = {});
  ~LsArPredictor() override;
  std::string name() const override { return "autoregressive_ls"; }
  void Update(double t_s, double position_mm) override;
  double Predict(double t_s) const override;

  // Whether it predicts (an eligible order and its history), else it holds the newest
  // measurement.
  bool ready() const;
  // The order predicting now (parameters, the offset included; 0 before any is eligible).
  int order() const;
  int stride() const { return stride_; }
  // Samples from a row's newest lag to its target: ⌈horizon × rate⌉.
  int horizon_steps() const { return h_ceil_; }
  double rate_hz() const { return dt_s_ > 0.0 ? 1.0 / dt_s_ : 0.0; }
  // Candidate solutions refused as ill-conditioned.
  std::size_t resets() const { return resets_; }
  // Changes when the model predicting becomes more flexible than any before it (the best
  // order exceeds every order used so far) or the learning is reset: its record so far is
  // that of what it outgrew, and a scorer may take recent_mse_mm2() instead.
  std::size_t generation() const { return generation_; }
  // The predicting order's a-priori squared error at the horizon, averaged over
  // validation_s (mm²; 0 when none predicts).
  double recent_mse_mm2() const;
  std::size_t history_resets() const { return counters_.history_resets; }
  // Intervals of 2–4 nominal ones (1–3 dropped samples), filled by interpolation.
  std::size_t filled_gaps() const { return counters_.filled; }
  const LsArPredictorOptions& options() const { return o_; }

 private:
  struct Candidate {
    int order = 0;
    Vector w;
    bool solved = false;
    double mse = 0.0;        // a-priori squared error, averaged over validation_s
    std::size_t scored = 0;  // rows scored a priori
  };
  struct Solver;  // the Cholesky factorisation's workspace (no allocation per refit)

  void Configure();  // stride, horizon, candidates, forgetting from the learned rate
  void ResetLearning();
  // Regressors of the largest order at history index j: [1, x[j−i·stride] − x[j]].
  void Regressors(std::size_t j, int p, Vector& u) const;
  void Learn();    // the row the newest sample completes
  void Refit();    // solve every candidate
  void Refresh();  // the cached prediction and the clamp range
  int Best() const;

  LsArPredictorOptions o_;
  SampleGrid grid_{"least-squares autoregressive predictor"};
  double dt_s_ = 0.0;  // nominal interval; 0 until learned
  int stride_ = 1;
  int width_ = 0;       // parameters of the largest candidate
  double h_steps_ = 1;  // horizon in samples (fractional)
  int h_ceil_ = 1;
  double lambda_ = 1.0;
  double alpha_ = 0.0;  // validation averaging gain
  int refit_every_ = 1;
  int since_refit_ = 0;
  std::vector<Candidate> candidates_;
  std::deque<double> x_;  // newest samples (at most the lags, horizon and range window)
  std::size_t keep_ = 0;
  Matrix g_;           // Σ λ^k u uᵀ (largest order)
  Vector b_;           // Σ λ^k u y
  double rows_ = 0.0;  // Σ λ^k: the effective rows learned
  std::size_t learned_ = 0;
  std::size_t resets_ = 0;
  GridCounters counters_;
  std::size_t generation_ = 0;
  int largest_used_ = 0;       // the largest order that has predicted since the last reset
  double predicted_mm_ = 0.0;  // x(t_n + horizon), clamped
  std::unique_ptr<Solver> solver_;
};

}  // namespace echoservo::estimation
