// Scores motion predictors on a trace: what `echoservo predict` prints.
//
// The measurements are the trace's samples (or, with `measurement_rate_hz`, the trace
// linearly interpolated at that rate, never across a gap). After each measurement at
// t_i every predictor predicts the position at t_i + latency, which is compared with the
// trace (or the `truth` trace, e.g. a noise-free column) interpolated there; prediction
// times past the end of the trace or inside a gap have no reference and are not scored.
// All predictors see the same measurements and are scored on the same instants: those
// after the heartbeat EKF has initialised. Predictors: the online competition
// (estimation/predictor_competition.h), i.e. what the live tracker ships, and each of its
// competitors (heartbeat EKF, autoregressive, zero-order hold, linear extrapolation,
// constant-velocity KF) alone. Units: s, mm.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "estimation/ar_reference.h"
#include "estimation/heart_rate.h"
#include "estimation/heartbeat_ekf.h"
#include "estimation/motion_trace.h"
#include "estimation/predictor_competition.h"

namespace echoservo::estimation {

struct PredictionScore {
  std::string name;
  double rms_mm = 0.0;
  double mae_mm = 0.0;
  double max_mm = 0.0;
};

struct PredictionRunOptions {
  double latency_s = 0.1;
  double measurement_rate_hz = 0.0;  // 0: every sample of the trace is a measurement
  HeartbeatEkfOptions ekf;
  const MotionTrace* truth = nullptr;  // reference for the errors; null: the trace itself
  bool keep_errors = false;            // fill PredictionRun::ekf_errors_mm
  bool keep_series = false;            // fill PredictionRun::series
  // The competition's choice rule (what ships): pick the best, or a weighted mix.
  Combination combination = Combination::kPickBest;
  double competition_window_s = 8.0;
  ArPredictorOptions ar;  // horizon_s is set to latency_s
  // The autoregressive reference (estimation/ar_reference.h; its latency is latency_s):
  // fitted on the first half of the measurements, scored on the second half beside every
  // predictor. Skipped (PredictionRun::reference_note says why) for a trace too short.
  bool reference = true;
  double heart_rate_window_s = 10.0;  // the newest span the reported heart rate is from
  ArReferenceOptions reference_options;
};

// The scores on the second half of the measurements (t ≥ split_s), where the reference is
// scored: the same instants for every predictor.
struct SecondHalfScores {
  double split_s = 0.0;
  std::size_t scored = 0;
  PredictionScore shipped;
  std::vector<PredictionScore> competitors;  // as PredictionRun::competitors
  PredictionScore reference;
};

struct PredictionRun {
  std::size_t measurements = 0;
  std::size_t scored = 0;
  std::size_t unscored_in_gaps = 0;  // prediction times inside a gap of the reference
  std::size_t gaps = 0;              // gaps in the measurements
  double scored_from_s = 0.0;        // first scored measurement (EKF initialised)
  double measurement_rate_hz = 0.0;  // median
  PredictionScore shipped;           // the competition's output: what the live tracker ships
  PredictionScore ekf;               // the heartbeat EKF alone
  std::vector<PredictionScore>
      baselines;  // zero_order_hold, linear_extrapolation, constant_velocity_kf
  // Every competitor alone (heartbeat_ekf, autoregressive, then the baselines), and the
  // fraction of scored measurements after which each drove the shipped output.
  std::vector<PredictionScore> competitors;
  std::vector<std::pair<std::string, double>> chosen_fraction;
  std::size_t switches = 0;        // changes of the competition's choice
  std::size_t reacquisitions = 0;  // the EKF's rate re-acquisitions
  int ar_order = 0;
  int ar_horizon_steps = 0;
  int ls_ar_order = 0;            // the least-squares AR's order at the end (0: none yet)
  int ls_ar_stride = 1;           // its samples between lags
  double blend_ekf_weight = 0.0;  // the blend's weight on the EKF at the end (NaN: none yet)
  // The EKF at the end of the trace.
  int harmonics = 0;
  bool respiration = false;         // the offset-rate state carried
  double offset_rate_q_mm_s = 0.0;  // its intensity (0 without)
  double rate_hz = 0.0;             // the EKF's filter rate at the end
  // The heart rate of the measurements' newest heart_rate_window_s (estimation/heart_rate.h):
  // what is reported as the heart rate (none unless significant).
  HeartRateEstimate heart_rate;
  double heart_rate_window_s = 0.0;
  double noise_mm = 0.0;
  std::size_t accepted = 0;
  std::size_t rejected = 0;
  std::size_t initialisations = 0;
  double cv_accel_psd_mm2_s3 = 0.0;
  // The autoregressive reference and the second half's scores; when has_reference is
  // false, reference_note says why (e.g. the trace is too short, and how long it must be).
  bool has_reference = false;
  std::string reference_note;
  ArReference reference;
  SecondHalfScores second_half;
  std::vector<double> ekf_errors_mm;      // with keep_errors: the EKF alone
  std::vector<double> shipped_errors_mm;  // with keep_errors: the competition's output
  // With keep_series, every scored instant: the time predicted (a measurement's time + the
  // latency, s), the reference there (mm), what shipped (mm) and the competitor chosen
  // (index into `competitors`).
  struct Series {
    std::vector<double> t_s, truth_mm, shipped_mm;
    std::vector<int> chosen;
  } series;
};

// Throws std::invalid_argument for a bad trace or options (naming where and why), and
// when the trace is too short for the EKF to initialise and leave anything to score.
PredictionRun RunPrediction(const MotionTrace& trace, const PredictionRunOptions& options);

}  // namespace echoservo::estimation
