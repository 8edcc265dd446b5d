// An online competition between motion predictors: the heartbeat EKF, two adaptive
// autoregressive predictors (recursive least squares, and least squares with its order chosen
// online), the EKF/AR blend and the baselines (zero-order hold, linear extrapolation,
// constant-velocity KF) run side by side on every measurement; each is scored on its own
// recent out-of-sample error at the working latency, and the best drives the output.
//
// In: positions (mm) stamped at acquisition (s, strictly increasing). Scoring: each
// competitor's prediction made at t for t + latency_s is compared, when a measurement at or
// after t + latency_s arrives, with the measurements linearly interpolated there (never
// across a gap); squared errors are averaged exponentially over window_s. Choice: the
// competitor with the lowest recent error, switched to only when it beats the current
// choice by the hysteresis fraction (no flapping); kWeighted instead mixes all by inverse
// mean squared error (measured worse, docs/predictor.md). The blend is w·EKF + (1 − w)·AR
// (the least-squares AR) with the convex weight minimising the pair's recent mean squared
// error (their errors' variances and covariance over the same window; Bates & Granger); it
// competes like the others, so it drives the output only where it has beaten the choice.
// Out: Predict(t) and Motion(), a FourierMotion for the servo, valid until newest +
// ekf.horizon_s: the EKF's own model when it is chosen; when the blend is, the EKF's model
// shifted to the blend's prediction at the latency (the servo keeps the heartbeat's shape);
// else 0 harmonics with the offset and drift (linear term) of the chosen predictor's
// forward prediction over [newest, newest + latency_s].
// Errors: the constructor throws std::invalid_argument for bad options; Update throws it
// for non-finite input or a time not after the previous one (nothing is changed then).
// Details: docs/predictor.md#what-ships-the-online-competition-estimationpredictor_competitionh
#pragma once

#include <cstddef>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "estimation/ar_predictor.h"
#include "estimation/fourier_motion.h"
#include "estimation/heartbeat_ekf.h"
#include "estimation/ls_ar_predictor.h"
#include "estimation/motion_predictor.h"

namespace echoservo::estimation {

enum class Combination { kPickBest, kWeighted };

class EkfArBlend;  // the blend competitor (predictor_competition.cc)

struct PredictorCompetitionOptions {
  double latency_s = 0.1;   // the horizon the competitors are scored at
  double window_s = 8.0;    // memory of the recent error (exponential, s)
  double hysteresis = 0.1;  // a challenger must be this fraction better than the choice
  int min_scored = 20;      // scored predictions before a competitor may be chosen
  Combination combination = Combination::kPickBest;
  HeartbeatEkfOptions ekf;
  ArPredictorOptions ar;       // its horizon_s is set to latency_s
  LsArPredictorOptions ls_ar;  // its horizon_s is set to latency_s
  ConstantVelocityKfOptions cv;
};

struct CompetitorStatus {
  std::string name;
  double recent_rms_mm = 0.0;  // √(recent mean squared error); 0 before any score
  std::size_t scored = 0;      // predictions scored so far
  std::size_t chosen = 0;      // measurements after which it drove the output
};

class PredictorCompetition final : public MotionPredictor {
 public:
  // Competitor indices, in order.
  enum Index : int { kEkf = 0, kAr, kArLs, kBlend, kZoh, kLinear, kCvKf, kCount };

  // Throws std::invalid_argument for bad options.
  explicit PredictorCompetition(PredictorCompetitionOptions options = {});

  std::string name() const override { return "competition"; }
  void Update(double t_s, double position_mm) override;
  double Predict(double t_s) const override;
  // The shipped motion model (see the file comment). Before any measurement: a constant 0
  // valid nowhere.
  FourierMotion Motion() const;

  int chosen() const { return chosen_; }
  const std::string& chosen_name() const { return status_[static_cast<std::size_t>(chosen_)].name; }
  const std::vector<CompetitorStatus>& competitors() const { return status_; }
  const MotionPredictor& competitor(int i) const {
    return *predictors_[static_cast<std::size_t>(i)];
  }
  const HeartbeatEkf& ekf() const { return *ekf_; }
  const ArPredictor& ar() const { return *ar_; }
  const LsArPredictor& ls_ar() const { return *ls_ar_; }
  // The blend's weight on the EKF (1 − it on the least-squares AR); NaN while it has no record.
  double blend_ekf_weight() const;
  std::size_t switches() const { return switches_; }
  const PredictorCompetitionOptions& options() const { return o_; }

 private:
  void Score(double t_s, double z);  // settle the predictions that are now due
  void Choose();
  void Weigh();
  void Restart(int i);  // a competitor's record starts afresh
  void Blend();         // the blend's weight from the pair's moments
  // Scored pairs before the blend has a weight: half the window (a weight from a few
  // pairs flaps; min_scored at least).
  std::size_t PairRecord() const;

  PredictorCompetitionOptions o_;
  std::vector<std::unique_ptr<MotionPredictor>> predictors_;
  HeartbeatEkf* ekf_ = nullptr;
  ArPredictor* ar_ = nullptr;
  LsArPredictor* ls_ar_ = nullptr;
  EkfArBlend* blend_ = nullptr;
  double pair_[3] = {0.0, 0.0, 0.0};  // EKF and LS-AR errors: E[e²], E[a²], E[e·a] (mm²)
  std::size_t pair_scored_ = 0;
  std::size_t ls_ar_generation_ = 0;
  bool ls_ar_trained_ = false;
  std::vector<CompetitorStatus> status_;
  std::vector<double> mse_;
  std::vector<double> weights_;  // kWeighted
  struct Pending {
    double target_s;
    double predicted_mm[kCount];
  };
  std::deque<Pending> pending_;
  bool any_ = false;
  double t_ = 0.0;
  double z_ = 0.0;
  double typical_dt_s_ = 0.0;  // running typical sampling interval (gap detection)
  int chosen_ = kZoh;
  std::size_t ekf_initialisations_ = 0;
  std::size_t switches_ = 0;
};

}  // namespace echoservo::estimation
