// Scores motion predictors on a trace: what `echoservo predict` prints.
//
// The measurements are the trace's samples (or, with `measurement_rate_hz`, the trace
// linearly interpolated at that rate, never across a gap). After each measurement at
// t_i every predictor predicts the position at t_i + latency, which is compared with the
// trace (or the `truth` trace, e.g. a noise-free column) interpolated there; prediction
// times past the end of the trace or inside a gap have no reference and are not scored.
// All predictors see the same measurements and are scored on the same instants: those
// after the heartbeat EKF has initialised. Units: s, mm.
#pragma once

#include <string>
#include <vector>

#include "estimation/heartbeat_ekf.h"
#include "estimation/motion_trace.h"

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
};

struct PredictionRun {
  std::size_t measurements = 0;
  std::size_t scored = 0;
  std::size_t unscored_in_gaps = 0;  // prediction times inside a gap of the reference
  std::size_t gaps = 0;              // gaps in the measurements
  double scored_from_s = 0.0;        // first scored measurement (EKF initialised)
  double measurement_rate_hz = 0.0;  // median
  PredictionScore ekf;
  std::vector<PredictionScore>
      baselines;  // zero_order_hold, linear_extrapolation, constant_velocity_kf
  // The EKF at the end of the trace.
  int harmonics = 0;
  bool respiration = false;         // the offset-rate state carried
  double offset_rate_q_mm_s = 0.0;  // its intensity (0 without)
  double rate_hz = 0.0;
  double noise_mm = 0.0;
  std::size_t accepted = 0;
  std::size_t rejected = 0;
  std::size_t initialisations = 0;
  double cv_accel_psd_mm2_s3 = 0.0;
  std::vector<double> ekf_errors_mm;  // with keep_errors
};

// Throws std::invalid_argument for a bad trace or options (naming where and why), and
// when the trace is too short for the EKF to initialise and leave anything to score.
PredictionRun RunPrediction(const MotionTrace& trace, const PredictionRunOptions& options);

}  // namespace echoservo::estimation
