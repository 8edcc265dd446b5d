// Is there a slow (respiratory) trend under the heartbeat? The test behind the heartbeat
// EKF's automatic respiration term (estimation/heartbeat_ekf.h).
//
// Over a window of measurements z (mm) at times t (s) and cardiac phases θ (rad, a
// fixed-rate phase at initialisation or the filter's own phase track later), a running
// least-squares fit of z on [1, u, u², u³, cos kθ, sin kθ (k = 1..N)], u = (t − t_first)/T
// (T the nominal window length), against the same fit with a constant offset. Each sample
// updates the normal equations (O(p²), p = 4 + 2N ≤ 28, a fraction of a microsecond); the
// evidence solves them once per window (two Cholesky factorisations of ≤ 28 × 28), so
// the test never costs an EKF update more than a few microseconds.
// The trend is significant when the BIC prefers it: n·ln(RSS_flat/RSS_trend) > 3·ln n
// (3 parameters more). Its curvature, the RMS over the samples of the cubic's second
// derivative (mm/s²), sets the respiration state's process noise.
#pragma once

#include <Eigen/Core>
#include <cstddef>

namespace echoservo::estimation {

struct TrendEvidence {
  std::size_t samples = 0;
  int parameters = 0;              // of the trend fit; 0: too few samples to fit
  double window_s = 0.0;           // newest − first sample time
  double rss_flat_mm2 = 0.0;       // harmonics and a constant offset
  double rss_trend_mm2 = 0.0;      // harmonics and the cubic trend
  double accel_rms_mm_s2 = 0.0;    // the trend's RMS second derivative over the samples
  double drift_mm_s = 0.0;         // the trend's slope at the newest sample
  bool Significant() const;        // BIC; false without enough samples
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
