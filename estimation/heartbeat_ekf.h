// The heartbeat EKF (after Yuen et al., MICCAI 2008 / IJRR 2009): an extended Kalman
// filter on a Fourier model of the cardiac cycle that predicts the target through the
// imaging delay and exports the predicted motion for the 1 kHz servo.
//
// State: offset c (mm), [offset rate ċ (mm/s) when the respiration term is carried: the
// slow low-order respiration term], the fundamental's cosine coefficient a₁ (its sine
// coefficient is fixed at 0 so that phase and shape are identifiable), aₖ, bₖ for
// k = 2..N (mm), the cardiac phase θ (rad) and the heart rate ω (rad/s).
// Process: θ += ω·dt, c += ċ·dt; random walks on the coefficients, offset, ċ and ω
// (continuous-time intensities in HeartbeatEkfOptions). Measurement: the target
// position along the catheter axis, z = c + a₁cos θ + Σ(aₖcos kθ + bₖsin kθ) + noise,
// time-stamped at acquisition (s) and processed in time order; predictions for the
// current time evaluate the model ahead of the newest acquisition.
//
// Life cycle: measurements are buffered until `init_window_s` of data is held, then a
// batch fit (estimation/harmonic_fit.h, with a cubic trend for slow respiration) gives
// the rate, the coefficients and the measurement noise, referred to the window's first
// sample; the filter then runs over the window (warm start), so that prediction starts
// from the phase and rate at its end although the heart rate changed within it.
// Automatic harmonic count: filters with 1..max_harmonics harmonics, each initialised
// (and warm-started) on the first 60 % of the window, predict the remaining 40 % one
// measurement ahead; the count with the smallest squared prediction error is used (the
// fewest within (0.01 mm)² a sample of it, for clean data; a count that loses the phase
// is no candidate). Automatic respiration: the offset-rate state is carried when the
// window's cubic trend is significant (BIC against a constant offset), with an
// intensity from the trend's curvature; while it is off, the same test runs on every
// further window of accepted measurements at the filter's phase track, and two windows
// in a row switch it on. Missing frames: the next update simply propagates across the
// gap (coasting). Outliers: a measurement whose innovation exceeds `gate_sigma`
// innovation standard deviations is rejected. Lost: after `max_rejections` consecutive
// rejections, or when the phase standard deviation exceeds `max_phase_sd_rad` (a long
// gap), the filter re-initialises from new data (keeping the measurements since the
// first rejection), choosing harmonics and respiration anew.
// Measurement noise: seeded by the fit, then the innovation average
// R ← 0.98·R + 0.02·max(ν² − HPHᵀ, (0.02 mm)²) over accepted measurements, unless set. While
// (re)initialising it predicts the newest measurement (zero-order hold).
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
  double rate_q_rad_s = 0.6;         // heart-rate variability
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
  SlowTrendWindow trend_;     // accepted measurements since the last respiration check
  bool trend_seen_ = false;   // the last check found a slow trend
  Vector x_;
  Matrix p_;
};

}  // namespace echoservo::estimation
