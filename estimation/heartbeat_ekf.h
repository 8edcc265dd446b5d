// The heartbeat EKF (Yuen et al., MICCAI 2008 / IJRR 2009): an extended Kalman filter on a
// Fourier model of the cardiac cycle that predicts the target through the imaging delay.
//
// In: the target position along the catheter axis (position_mm, image mm), stamped at
// acquisition (t_s, s; strictly increasing). Out: Predict(t_s) in mm, and Motion(), a
// FourierMotion the 1 kHz servo evaluates, valid until the newest acquisition + horizon_s.
// Buffers until init_window_s of data is held (predicting the newest measurement), then
// filters; gates outliers (gate_sigma) and re-initialises when lost or after a long gap.
// Errors: the constructor throws std::invalid_argument for inconsistent options; Process
// throws it for a NaN or infinite input or a time not after the previous one.
// Details: docs/predictor.md#the-heartbeat-ekf-estimationheartbeat_ekfh
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <deque>
#include <utility>

#include "estimation/fourier_motion.h"
#include "estimation/motion_predictor.h"
#include "estimation/slow_trend.h"

namespace echoservo::estimation {

// The offset-rate (respiration) state: automatic (decided at each (re)initialisation
// from the window's slow trend, and switched on later when the trend appears), or forced.
enum class Respiration { kAuto, kOff, kOn };

struct HeartbeatEkfOptions {
  int harmonics = 0;  // 0: automatic (cross-validated at initialisation) up to max_harmonics; ≤ 12
  int max_harmonics = 8;
  Respiration respiration = Respiration::kAuto;
  double min_rate_hz = 0.6;
  double max_rate_hz = 3.0;
  double init_window_s = 4.0;
  double noise_mm = 0.0;  // measurement σ; 0: the initial fit's residual (floored at 0.02 mm)
  // Random-walk intensities (standard deviation growth per √s).
  double coefficient_q_mm = 0.02;
  double offset_q_mm = 0.1;
  // With respiration; 0: from the window's cubic trend, ā·√(T/π) for an RMS trend
  // acceleration ā (mm/s²) over T seconds (floored at 0.3 mm/s/√s).
  double offset_rate_q_mm_s = 0.0;
  double rate_q_rad_s = 0.6;  // heart-rate variability
  double phase_q_rad = 0.02;
  double gate_sigma = 4.0;
  int max_rejections = 5;
  double max_phase_sd_rad = 0.8;
  double horizon_s = 0.5;  // the exported model's validity past the newest measurement
};

enum class UpdateResult { kBuffering, kInitialised, kAccepted, kRejected, kLost };

class HeartbeatEkf final : public MotionPredictor {
 public:
  static constexpr int kMaxHarmonics = 12;
  static constexpr int kMaxState = 2 + 1 + 2 * (kMaxHarmonics - 1) + 2;
  using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxState, 1>;
  using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxState, kMaxState>;

  // Throws std::invalid_argument for inconsistent options.
  explicit HeartbeatEkf(HeartbeatEkfOptions options = {});

  std::string name() const override { return "heartbeat_ekf"; }
  void Update(double t_s, double position_mm) override { Process(t_s, position_mm); }
  UpdateResult Process(double t_s, double position_mm);
  double Predict(double t_s) const override;

  // The predicted motion from the newest measurement on, valid until newest + horizon_s.
  // Before initialisation: the newest measurement as a constant, valid until then + 0.
  FourierMotion Motion() const;

  bool initialised() const { return initialised_; }
  int harmonics() const { return harmonics_; }
  double rate_hz() const;
  double noise_mm() const { return noise_mm_; }
  // Whether the current initialisation carries the offset-rate state, and its intensity.
  bool respiration() const { return respiration_; }
  double offset_rate_q_mm_s() const { return respiration_ ? offset_rate_q_mm_s_ : 0.0; }
  double phase_sd_rad() const;
  const HeartbeatEkfOptions& options() const { return o_; }
  std::size_t accepted() const { return accepted_; }
  std::size_t rejected() const { return rejected_; }
  std::size_t initialisations() const { return initialisations_; }

 private:
  void Initialise();
  int ChooseHarmonics() const;
  // Sets respiration_ and its intensity from a window's slow-trend evidence.
  void ChooseRespiration(const TrendEvidence& evidence);
  // While respiration is automatic and off: the test on the newest window of accepted
  // measurements (at the filter's phase track); adds the offset-rate state when it
  // passes twice in a row.
  void CheckRespiration();
  // Time and measurement update at t_s: kAccepted, kRejected (gated, state only
  // propagated) or kLost (phase too uncertain); no bookkeeping of the life cycle.
  UpdateResult Correct(double t_s, double z_mm);
  void TimeUpdate(double dt);
  // The measurement model at phase θ (offset and harmonics); fills ∂h/∂x when h is set.
  double ShapeAt(double theta, Vector* h) const;
  int StateSize() const;
  int FirstCoefficient() const { return respiration_ ? 2 : 1; }
  int PhaseIndex() const { return StateSize() - 2; }

  HeartbeatEkfOptions o_;
  bool initialised_ = false;
  int harmonics_ = 0;
  bool respiration_ = false;
  double offset_rate_q_mm_s_ = 0.0;
  double noise_mm_ = 0.0;
  double t_ = 0.0;
  double last_mm_ = 0.0;
  bool any_ = false;
  int consecutive_rejections_ = 0;
  std::size_t accepted_ = 0;
  std::size_t rejected_ = 0;
  std::size_t initialisations_ = 0;
  std::deque<std::pair<double, double>> buffer_;  // (t, z) while (re)initialising
  std::deque<std::pair<double, double>> recent_;  // rejected run, for re-initialisation
  SlowTrendWindow trend_;    // accepted measurements since the last respiration check
  bool trend_seen_ = false;  // the last check found a slow trend
  Vector x_;
  Matrix p_;
};

}  // namespace echoservo::estimation
