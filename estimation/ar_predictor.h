// An adaptive direct-horizon autoregressive predictor: recursive least squares with
// forgetting on the newest `order` measurements, predicting the position h samples ahead
// directly (h = horizon_s × the measurement rate) rather than iterating a one-step model.
//
// In: positions (mm) stamped at acquisition (s, strictly increasing), at a roughly constant
// rate (learned from the first intervals). Model: x[n+h] − x[n] = w₀ + Σ_{i=1..p−1}
// wᵢ (x[n−i] − x[n]) (offset-free: a breathing baseline needs no refit; w = 0 is the
// zero-order hold). Out: Predict(t) in mm; between the newest measurement and the horizon
// it interpolates linearly, past it it holds. Bounded: the prediction is clamped to the
// recent range ± a margin. Falls back to the zero-order hold until it has trained on
// enough pairs, and after an irregular interval or a gap (history reset, weights kept; 1–3
// dropped samples on the grid are filled by linear interpolation instead) or
// an ill-conditioned solution (weights reset). Robust: the a-priori error of each update
// is clipped at 3 robust σ (outliers, heavy-tailed noise).
// Errors: the constructor throws std::invalid_argument for bad options; Update throws it
// for a non-finite input or a time not after the previous one.
// Details: docs/predictor.md#the-autoregressive-predictor-estimationar_predictorh
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <deque>
#include <string>

#include "estimation/motion_predictor.h"
#include "estimation/sample_grid.h"

namespace echoservo::estimation {

struct ArPredictorOptions {
  double horizon_s = 0.1;  // how far ahead it predicts (the imaging latency)
  double history_s = 1.0;  // order p = history_s × rate (about one heartbeat)
  int min_order = 4;
  int max_order = 40;
  double memory_s = 15.0;         // forgetting λ = 1 − 1/(memory_s × rate)
  double prior_var = 1.0;         // P₀ = prior_var·I (1/ridge, per mm² of regressor)
  double margin_fraction = 0.25;  // clamp to [min − m, max + m], m = fraction × range
  double range_window_s = 3.0;    // the "recent" range for the clamp
  double warmup_factor = 2.0;     // trained pairs ≥ warmup_factor × parameters before use
  double max_weight_sum = 50.0;   // Σ|w| beyond this: ill-conditioned, reset
};

class ArPredictor final : public MotionPredictor {
 public:
  static constexpr int kMaxParams = 64;
  using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxParams, 1>;
  using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxParams, kMaxParams>;

  // Throws std::invalid_argument for inconsistent options.
  explicit ArPredictor(ArPredictorOptions options = {});
  std::string name() const override { return "autoregressive"; }
  void Update(double t_s, double position_mm) override;
  double Predict(double t_s) const override;

  // Whether it predicts (trained), else it holds the newest measurement.
  bool ready() const;
  int order() const { return order_; }
  int horizon_steps() const { return h_; }
  double rate_hz() const { return dt_s_ > 0.0 ? 1.0 / dt_s_ : 0.0; }
  std::size_t resets() const { return resets_; }
  std::size_t history_resets() const { return counters_.history_resets; }
  // Intervals of 2–4 nominal ones (1–3 dropped samples), filled by interpolation.
  std::size_t filled_gaps() const { return counters_.filled; }
  const ArPredictorOptions& options() const { return o_; }

 private:
  void Configure();  // order, horizon, forgetting from the learned rate
  void ResetWeights();
  // Regressors at history index j (0 = oldest kept): [1, x[j−i] − x[j], i = 1..p−1].
  void Regressors(std::size_t j, Vector& u) const;
  void Train();    // one RLS update with the newest complete pair
  void Refresh();  // the cached prediction and the clamp range

  ArPredictorOptions o_;
  SampleGrid grid_{"autoregressive predictor"};
  double dt_s_ = 0.0;  // nominal interval; 0 until learned
  int order_ = 0;
  int h_ = 1;
  double lambda_ = 1.0;
  std::deque<double> x_;  // newest samples (at most max(order + h, range window))
  std::size_t keep_ = 0;
  Vector w_;
  Matrix p_;
  double abs_err_ = 0.0;  // exponentially weighted mean |a-priori error| (mm)
  std::size_t trained_ = 0;
  std::size_t resets_ = 0;
  GridCounters counters_;
  double predicted_mm_ = 0.0;  // x[n + h], clamped
};

}  // namespace echoservo::estimation
