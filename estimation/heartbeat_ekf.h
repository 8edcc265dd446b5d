// The heartbeat EKF (Yuen et al., MICCAI 2008 / IJRR 2009): an extended Kalman filter on a
// Fourier model of the cardiac cycle that predicts the target through the imaging delay.
//
// In: the target position along the catheter axis (position_mm, image mm), stamped at
// acquisition (t_s, s; strictly increasing). Out: Predict(t_s) in mm, and Motion(), a
// FourierMotion the 1 kHz servo evaluates, valid until the newest acquisition + horizon_s.
// Buffers until init_window_s of data is held (predicting the newest measurement), then
// filters; gates outliers (gate_sigma) and re-initialises when lost or after a long gap.
// The heart rate is bounded to a physiological band (default 30–220 bpm, widened to the
// search range when that is wider) and re-acquired from the newest window of data (a batch
// spectral fit) when the filter's rate reaches the band's edge, most innovations stay
// large, the window's own fundamental (estimation/heart_rate.h) is significant and more
// than 15 % from the filter's rate (a sub-harmonic or harmonic lock), or the state leaves
// the window's range; with a cooldown between re-acquisitions. Every (re)acquisition takes
// its rate from that fundamental when it is significant. Predict is bounded to the newest window's
// range ± half of it. Errors: the constructor throws std::invalid_argument for inconsistent
// options; Process throws it for a NaN or infinite input or a time not after the previous one.
// Details: docs/predictor.md#the-heartbeat-ekf-estimationheartbeat_ekfh
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <deque>
#include <utility>
#include <vector>

#include "estimation/fourier_motion.h"
#include "estimation/heart_rate.h"
#include "estimation/motion_predictor.h"
#include "estimation/slow_trend.h"
#include "formats/parameter_spec.h"

namespace echoservo::estimation {

// The offset-rate (respiration) state: automatic (decided at each (re)initialisation
// from the window's slow trend, and switched on later when the trend appears), or forced.
enum class Respiration { kAuto, kOff, kOn };

// The EKF's tunable parameters (formats/parameter_spec.h): declared once, read by the
// defaults below, by the constructor's validation and by the pipeline's registry
// (live/pipeline_parameters.h, stage "predictor"; the live tracker's own defaults for the
// harmonics and the window: live::TrackerNodeOptions::DefaultEkfOptions).
namespace params {
inline constexpr formats::ParameterSpec kHarmonics{
    "predictor.harmonics",
    "1",
    formats::ParameterKind::kInteger,
    0,
    12,
    0,
    "EKF harmonics of the heartbeat's shape; 0: chosen at initialisation (cross-validated) up "
    "to predictor.max_harmonics"};
inline constexpr formats::ParameterSpec kMaxHarmonics{
    "predictor.max_harmonics",
    "1",
    formats::ParameterKind::kInteger,
    1,
    12,
    8,
    "the automatic harmonic choice's upper end (used when predictor.harmonics is 0)"};
inline constexpr formats::ParameterSpec kInitWindowS{
    "predictor.init_window_s",
    "s",
    formats::ParameterKind::kReal,
    1.7,
    30,
    4.0,
    "EKF initial (and re-acquisition) window; >= one beat at its lowest rate (0.6 Hz: 1.67 s)"};
inline constexpr formats::ParameterSpec kNoiseMm{
    "predictor.noise_mm",
    "mm",
    formats::ParameterKind::kReal,
    0,
    5,
    0.0,
    "EKF measurement sigma; 0: the initial fit's residual (floored at 0.02 mm)"};
inline constexpr formats::ParameterSpec kCoefficientQMm{
    "predictor.coefficient_q_mm",
    "mm/sqrt(s)",
    formats::ParameterKind::kReal,
    1e-4,
    1,
    0.02,
    "EKF random walk of the Fourier coefficients (the beat's shape changing)"};
inline constexpr formats::ParameterSpec kOffsetQMm{
    "predictor.offset_q_mm",
    "mm/sqrt(s)",
    formats::ParameterKind::kReal,
    1e-3,
    5,
    0.1,
    "EKF random walk of the motion's offset (drift, slow respiration)"};
inline constexpr formats::ParameterSpec kRateQRadS{
    "predictor.rate_q_rad_s",
    "rad/s/sqrt(s)",
    formats::ParameterKind::kReal,
    1e-3,
    10,
    0.6,
    "EKF random walk of the heart rate (heart-rate variability)"};
inline constexpr formats::ParameterSpec kPhaseQRad{"predictor.phase_q_rad",
                                                   "rad/sqrt(s)",
                                                   formats::ParameterKind::kReal,
                                                   1e-4,
                                                   1,
                                                   0.02,
                                                   "EKF random walk of the cardiac phase"};
inline constexpr formats::ParameterSpec kGateSigma{
    "predictor.gate_sigma",
    "1",
    formats::ParameterKind::kReal,
    1,
    20,
    4.0,
    "EKF outlier gate: measurements further than this many predicted sigma are rejected"};
}  // namespace params

struct HeartbeatEkfOptions {
  int harmonics = static_cast<int>(
      params::kHarmonics.default_value);  // 0: automatic (cross-validated at initialisation) up to
                                          // max_harmonics; ≤ 12
  int max_harmonics = static_cast<int>(params::kMaxHarmonics.default_value);
  Respiration respiration = Respiration::kAuto;
  double min_rate_hz = 0.6;
  double max_rate_hz = 3.0;
  double init_window_s = params::kInitWindowS.default_value;
  double noise_mm =
      params::kNoiseMm
          .default_value;  // measurement σ; 0: the initial fit's residual (floored at 0.02 mm)
  // Random-walk intensities (standard deviation growth per √s).
  double coefficient_q_mm = params::kCoefficientQMm.default_value;
  double offset_q_mm = params::kOffsetQMm.default_value;
  // With respiration; 0: from the window's cubic trend, ā·√(T/π) for an RMS trend
  // acceleration ā (mm/s²) over T seconds (floored at 0.3 mm/s/√s).
  double offset_rate_q_mm_s = 0.0;
  double rate_q_rad_s = params::kRateQRadS.default_value;  // heart-rate variability
  double phase_q_rad = params::kPhaseQRad.default_value;
  double gate_sigma = params::kGateSigma.default_value;
  int max_rejections = 5;
  double max_phase_sd_rad = 0.8;
  double horizon_s = 0.5;  // the exported model's validity past the newest measurement
  // The rate band the filter's ω is clamped to (Hz; widened to [min_rate_hz, max_rate_hz]
  // when that is wider, e.g. for breathing traces), and re-acquisition: when ω reaches the
  // band's edge, or the fraction of measurements whose normalised innovation squared ν²/S
  // exceeds reacquire_nis (2σ: 4.6 % for a consistent filter), averaged over
  // reacquire_beats beats, exceeds reacquire_fraction, the rate, phase and shape are
  // refitted on the newest init_window_s of measurements (same harmonic count).
  double band_min_hz = 0.5;           // 30 bpm
  double band_max_hz = 220.0 / 60.0;  // 220 bpm
  double reacquire_nis = 4.0;
  double reacquire_fraction = 0.5;
  double reacquire_beats = 2.0;
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
  // Re-acquisitions (docs/predictor.md#heart-rate-band-and-re-acquisition; they are part
  // of initialisations()).
  std::size_t reacquisitions() const { return reacquisitions_; }
  // The band ω is held in (Hz): the physiological band widened to the search range.
  double band_min_hz() const { return std::min(o_.band_min_hz, o_.min_rate_hz); }
  double band_max_hz() const { return std::max(o_.band_max_hz, o_.max_rate_hz); }
  // The fraction of innovations with ν²/S > reacquire_nis over ~reacquire_beats beats
  // (≈ 0.05 when the filter is consistent).
  double large_innovation_fraction() const { return nis_mean_; }

 private:
  // `keep_harmonics` > 0: refit at that count (re-acquisition) instead of choosing one.
  void Initialise(int keep_harmonics = 0);
  // After an accepted or rejected measurement: the NIS average and the re-acquisition test.
  void Watch(double dt_s, double nis, bool out_of_band);
  // The fundamental of a window of measurements, over the search range.
  HeartRateEstimate WindowHeartRate(const std::vector<double>& t_s,
                                    const std::vector<double>& z_mm) const;
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
  std::size_t reacquisitions_ = 0;
  double nis_mean_ = 0.0;  // the large-innovation fraction
  double since_init_s_ = 0.0;
  double since_rate_check_s_ = 0.0;
  double window_lo_mm_ = 1.0;  // the newest window's range (Predict's bound); lo > hi: none
  double window_hi_mm_ = 0.0;
  double cooldown_s_ = 0.0;   // re-acquisition on large innovations waits this long (s)
  bool out_of_band_ = false;  // set by Correct when ω was clamped
  double last_nis_ = 1.0;     // of the newest Correct
  std::deque<std::pair<double, double>> window_;  // the newest init_window_s of measurements
  std::deque<std::pair<double, double>> buffer_;  // (t, z) while (re)initialising
  std::deque<std::pair<double, double>> recent_;  // rejected run, for re-initialisation
  SlowTrendWindow trend_;    // accepted measurements since the last respiration check
  bool trend_seen_ = false;  // the last check found a slow trend
  Vector x_;
  Matrix p_;
};

}  // namespace echoservo::estimation
