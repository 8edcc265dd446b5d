#include "control/experiments/synthetic_motion.h"

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

#include "control/trajectory.h"

namespace echoservo::control {

SyntheticMotionOptions MitralHrvDefaults() {
  SyntheticMotionOptions o;
  o.rsa_bpm = 3.0;
  o.wander_bpm = 3.0;
  o.noise_mm = 0.3;
  return o;
}

SyntheticMotion MakeSyntheticMotion(const SyntheticMotionOptions& o) {
  auto finite_nonneg = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!(o.duration_s > 0.0 && o.duration_s <= 3600.0 && o.sample_rate_hz >= 1.0 &&
        o.sample_rate_hz <= 10000.0 && finite_nonneg(o.rsa_bpm) && finite_nonneg(o.wander_bpm) &&
        o.wander_tau_s > 0.0 && finite_nonneg(o.respiration_mm) && o.respiration_hz > 0.0 &&
        finite_nonneg(o.noise_mm) && std::isfinite(o.rate_drift_bpm_per_min))) {
    throw std::invalid_argument(
        "synthetic motion: duration in (0, 3600] s, sample rate in [1, 10000] Hz, and "
        "non-negative finite variability, respiration and noise");
  }
  MitralOptions mo;
  mo.heart_rate_bpm = o.heart_rate_bpm;
  mo.peak_to_peak_mm = o.peak_to_peak_mm;
  mo.harmonics = o.harmonics;
  const MitralTrajectory mitral(mo);  // validates rate, amplitude and harmonics
  estimation::FourierMotion shape = mitral.motion();
  shape.t0_s = 0.0;
  shape.phase0_rad = 0.0;
  shape.frequency_hz = 1.0 / (2.0 * std::numbers::pi);  // evaluate at t = phase

  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double dt = 1.0 / o.sample_rate_hz;
  const auto n = static_cast<std::size_t>(std::floor(o.duration_s * o.sample_rate_hz)) + 1;
  const double resp_phase =
      2.0 * std::numbers::pi * std::uniform_real_distribution<double>(0.0, 1.0)(rng);
  SyntheticMotion out;
  out.measured.source = "synthetic mitral trace";
  out.measured.column = "position";
  double phase = 0.0;
  double wander = 0.0;
  const double decay = std::exp(-dt / o.wander_tau_s);
  const double kick = o.wander_bpm * std::sqrt(1.0 - decay * decay);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) * dt;
    const double resp_arg = 2.0 * std::numbers::pi * o.respiration_hz * t + resp_phase;
    const double bpm = o.heart_rate_bpm + o.rate_drift_bpm_per_min * t / 60.0 +
                       o.rsa_bpm * std::sin(resp_arg) + wander;
    if (!(bpm >= 20.0 && bpm <= 240.0)) {
      throw std::invalid_argument("synthetic motion: the heart rate leaves [20, 240] bpm at t = " +
                                  std::to_string(t) + " s");
    }
    const double x = shape.Position(phase) + o.respiration_mm * std::sin(resp_arg);
    out.measured.t_s.push_back(t);
    out.truth_mm.push_back(x);
    out.measured.position_mm.push_back(x + o.noise_mm * gauss(rng));
    out.heart_rate_bpm.push_back(bpm);
    phase += 2.0 * std::numbers::pi * bpm / 60.0 * dt;
    wander = decay * wander + kick * gauss(rng);
  }
  return out;
}

}  // namespace echoservo::control
