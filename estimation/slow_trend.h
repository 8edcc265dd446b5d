// Is there a slow (respiratory) trend under the heartbeat? The test behind the heartbeat
// EKF's automatic respiration term (estimation/heartbeat_ekf.h).
//
// In: measurements z (mm) at times t (s) with their cardiac phases θ (rad). Out: the
// evidence of a cubic trend against a constant offset under the same harmonics (BIC), and
// the trend's RMS curvature (mm/s²) that sets the respiration state's process noise.
// Add updates normal equations, O(p²) with p ≤ 28; Evidence solves them (a few µs).
// Errors: Reset throws std::invalid_argument for harmonics outside 1..12 or nominal_s ≤ 0.
// Details: docs/predictor.md#the-slow-trend-test-estimationslow_trendh
#pragma once

#include <Eigen/Core>
#include <cstddef>

namespace echoservo::estimation {

struct TrendEvidence {
  std::size_t samples = 0;
  int parameters = 0;            // of the trend fit; 0: too few samples to fit
  double window_s = 0.0;         // newest − first sample time
  double rss_flat_mm2 = 0.0;     // harmonics and a constant offset
  double rss_trend_mm2 = 0.0;    // harmonics and the cubic trend
  double accel_rms_mm_s2 = 0.0;  // the trend's RMS second derivative over the samples
  double drift_mm_s = 0.0;       // the trend's slope at the newest sample
  bool Significant() const;      // BIC; false without enough samples
};

class SlowTrendWindow {
 public:
  static constexpr int kTrendOrder = 3;
  static constexpr int kMaxHarmonics = 12;
  static constexpr int kMaxColumns = kTrendOrder + 1 + 2 * kMaxHarmonics;

  // Starts an empty window for `harmonics` (1..12) over about `nominal_s` seconds (> 0).
  // Throws std::invalid_argument otherwise.
  void Reset(int harmonics, double nominal_s);
  void Add(double t_s, double phase_rad, double z_mm);
  std::size_t samples() const { return samples_; }
  double span_s() const { return samples_ == 0 ? 0.0 : newest_s_ - first_s_; }
  // The fits on the samples so far; not significant below twice as many samples as
  // parameters.
  TrendEvidence Evidence() const;

 private:
  using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxColumns, kMaxColumns>;
  using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxColumns, 1>;
  int columns_ = 0;
  double nominal_s_ = 1.0;
  std::size_t samples_ = 0;
  double first_s_ = 0.0;
  double newest_s_ = 0.0;
  double z0_mm_ = 0.0;  // the first sample, subtracted from all (conditioning)
  Matrix gram_;         // XᵀX (upper triangle)
  Vector xty_;          // Xᵀz
  double zz_ = 0.0;     // zᵀz
};

}  // namespace echoservo::estimation
