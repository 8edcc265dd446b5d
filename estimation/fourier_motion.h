// A periodic motion as a truncated Fourier series: the heartbeat model.
//
// x(t) = offset + drift·(t − t0) + Σ_{k=1..N} [a_k cos(k·φ(t)) + b_k sin(k·φ(t))],
// φ(t) = 2π·f·(t − t0) + φ0
// Positions in mm, time in s, frequency in Hz. The heartbeat estimator
// (estimation/heartbeat_ekf.h) exports its prediction in this form with a validity
// horizon, so the 1 kHz servo can evaluate position, velocity and acceleration between
// volumes; `drift` is its slow low-order (respiration) term, 0 otherwise. Reference
// trajectories use it too.
// Evaluation uses the angle-addition recurrence: one sin/cos pair per call.
#pragma once

#include <limits>
#include <numbers>
#include <vector>

namespace echoservo::estimation {

inline constexpr double kTwoPi = 2.0 * std::numbers::pi;  // rad per cycle

struct MotionSample {
  double position_mm = 0.0;
  double velocity_mm_s = 0.0;
  double acceleration_mm_s2 = 0.0;
};

struct FourierMotion {
  double t0_s = 0.0;
  double phase0_rad = 0.0;
  double frequency_hz = 1.0;
  double offset_mm = 0.0;
  double drift_mm_s = 0.0;     // linear term (slow respiration), about t0
  std::vector<double> cos_mm;  // a_1..a_N
  std::vector<double> sin_mm;  // b_1..b_N
  double valid_until_s = std::numeric_limits<double>::infinity();

  bool operator==(const FourierMotion&) const = default;
  std::size_t harmonics() const { return cos_mm.size(); }
  // Throws std::invalid_argument for mismatched or non-finite coefficients, or a
  // non-positive frequency.
  void Validate() const;
  MotionSample Evaluate(double t_s) const;
  double Position(double t_s) const { return Evaluate(t_s).position_mm; }
  bool ValidAt(double t_s) const { return t_s <= valid_until_s; }

  // Fits N harmonics to one period sampled uniformly (samples[i] at phase 2π·i/n).
  static FourierMotion FromPeriodSamples(const std::vector<double>& samples, int harmonics,
                                         double frequency_hz);
};

}  // namespace echoservo::estimation
