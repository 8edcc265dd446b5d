// Is there a heartbeat in the target trace at all? The gate in front of the heartbeat EKF's
// published prediction (live/tracker_node.h): a periodicity and amplitude significance test
// on the newest window of measurements, so that a static or non-periodic target (detection
// noise, a random walk, a slow drift) is not published as an invented heartbeat.
//
// In: target positions along the catheter axis (mm) stamped at acquisition (s, strictly
// increasing). Out: HeartbeatEvidence from Evaluate(): significant or not, and why.
// A trace is significant when all three hold on the window:
//  1. periodicity: the harmonic regression (K harmonics + a quadratic trend) at the best rate
//     of the heart-rate band beats the trend alone in an F-test whose family-wise false-alarm
//     probability over the band (Bonferroni over its independent frequencies) is below
//     `false_alarm`;
//  2. repetition: at that rate's period P the detrended trace repeats: its variance exceeds
//     (1 + min_repeat_snr)× half the mean square of y(t + P) − y(t) (a random walk or drift
//     does not repeat; a heartbeat repeats to the noise);
//  3. amplitude: the fitted periodic part's peak to peak ≥ min_p2p_sigma × the fit's residual
//     σ and ≥ min_p2p_mm.
// Errors: the constructor throws std::invalid_argument for inconsistent options; Add throws it
// for a NaN/infinite input or a time not after the previous one.
// Details: docs/predictor.md#the-heartbeat-significance-test-estimationheartbeat_significanceh
#pragma once

#include <cstddef>
#include <deque>
#include <string>
#include <utility>

namespace echoservo::estimation {

struct HeartbeatSignificanceOptions {
  // The physiological heart-rate band, 30–210 bpm (docs/predictor.md for its source).
  double min_rate_hz = 0.5;
  double max_rate_hz = 3.5;
  double window_s = 5.0;        // newest measurements tested: 2.5 beats at min_rate_hz
  double min_beats = 2.5;       // rates tested hold at least this many beats in the window (≥ 2)
  int harmonics = 3;            // K of the regression (fewer where k·rate nears Nyquist)
  double false_alarm = 1e-3;    // family-wise, per evaluation, on white Gaussian noise
  double min_repeat_snr = 1.5;  // repeating variance / non-repeating variance
  double min_p2p_sigma = 4.0;   // p2p ≥ this × residual σ (±2σ of one detection)
  double min_p2p_mm = 0.5;      // and at least this (one voxel of the live volumes)
};

struct HeartbeatEvidence {
  bool significant = false;
  std::string reason;  // why (not): "no significant heartbeat: peak SNR 2.1 < 6.3 …"
  std::size_t samples = 0;
  double span_s = 0.0;
  double rate_hz = 0.0;        // the best rate of the band (0 before any evaluation)
  double peak_snr = 0.0;       // the F statistic at that rate: explained / residual variance
  double snr_threshold = 0.0;  // F critical at the family-wise false-alarm probability
  double p_value = 1.0;        // family-wise (Bonferroni) p of the peak
  double repeat_snr = 0.0;     // see the file comment
  double p2p_mm = 0.0;         // of the fitted periodic part
  double noise_mm = 0.0;       // residual σ of the harmonic fit
  // 0 when not significant, else 1 − p_value.
  double confidence() const { return significant ? 1.0 - p_value : 0.0; }
};

class HeartbeatSignificance {
 public:
  // Throws std::invalid_argument for inconsistent options.
  explicit HeartbeatSignificance(HeartbeatSignificanceOptions options = {});

  // Adds a measurement and drops those older than window_s (O(1)).
  void Add(double t_s, double position_mm);
  // Tests the window (≈0.2 ms for 100 samples and the default band); updates evidence().
  const HeartbeatEvidence& Evaluate();
  const HeartbeatEvidence& evidence() const { return evidence_; }
  const HeartbeatSignificanceOptions& options() const { return o_; }
  void Reset();

 private:
  HeartbeatSignificanceOptions o_;
  std::deque<std::pair<double, double>> window_;  // (t, z)
  HeartbeatEvidence evidence_;
};

// P(F > f) for F ~ F(d1, d2): the survival function of Fisher's F distribution.
double FisherFSurvival(double f, double d1, double d2);

}  // namespace echoservo::estimation
