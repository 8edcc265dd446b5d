#include "control/experiments/calibration.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace echoservo::control {

void ProbeOptions::Validate() const {
  auto check = [](bool ok, const std::string& field) {
    if (!ok) throw std::invalid_argument("calibration: invalid '" + field + "'");
  };
  check(speeds_mm_s.size() >= 2, "speeds_mm_s (need at least 2 speeds)");
  for (double v : speeds_mm_s)
    check(std::isfinite(v) && v > 0.0 && v <= 400.0, "speeds_mm_s (each in (0, 400])");
  check(std::isfinite(stroke_amplitude_mm) && stroke_amplitude_mm > 0.5 &&
            stroke_amplitude_mm <= 20.0,
        "stroke_amplitude_mm (in (0.5, 20])");
  check(strokes_per_speed >= 1 && strokes_per_speed <= 20, "strokes_per_speed");
  check(std::isfinite(backlash_amplitude_mm) && backlash_amplitude_mm > 0.5 &&
            backlash_amplitude_mm <= 20.0,
        "backlash_amplitude_mm (in (0.5, 20])");
  check(std::isfinite(backlash_frequency_hz) && backlash_frequency_hz > 0.0 &&
            backlash_frequency_hz <= 10.0,
        "backlash_frequency_hz (in (0, 10])");
  check(backlash_cycles >= 2 && backlash_cycles <= 50, "backlash_cycles (in [2, 50])");
}

std::vector<FrictionSample> ProbeFriction(hw::HardwareInterface& hardware, ServoConfig servo,
                                          const ProbeOptions& options) {
  options.Validate();
  servo.feedforward = FrictionFeedforward{};
  std::vector<FrictionSample> samples;
  for (double speed : options.speeds_mm_s) {
    const TriangleTrajectory stroke(options.stroke_amplitude_mm, speed);
    ServoLoop loop(hardware, servo);
    NoCompensation none;
    const double duration = stroke.period_s() * (options.strokes_per_speed + 0.25);
    const std::vector<CycleRecord> records = RunFixedStep(loop, stroke, none, duration);
    // Steady middle of each stroke, after the first quarter period (the start-up); the
    // velocity is the encoder's (the base may still be settling after a corner).
    double sum[2] = {0.0, 0.0};
    double vel[2] = {0.0, 0.0};
    int count[2] = {0, 0};
    for (std::size_t i = 1; i < records.size(); ++i) {
      const CycleRecord& r = records[i];
      if (r.t_s < 0.25 * stroke.period_s()) continue;
      const MotionSample ref = stroke.Evaluate(r.t_s);
      if (std::abs(ref.position_mm) > 0.5 * options.stroke_amplitude_mm) continue;
      const int dir = ref.velocity_mm_s > 0.0 ? 0 : 1;
      sum[dir] += r.force_n;
      vel[dir] += (r.base_mm - records[i - 1].base_mm) / (r.t_s - records[i - 1].t_s);
      ++count[dir];
    }
    for (int dir = 0; dir < 2; ++dir) {
      if (count[dir] == 0) continue;
      samples.push_back({vel[dir] / count[dir], sum[dir] / count[dir]});
    }
  }
  return samples;
}

HysteresisWidth ProbeBacklash(hw::HardwareInterface& hardware, ServoConfig servo,
                              const ProbeOptions& options) {
  options.Validate();
  servo.feedforward = FrictionFeedforward{};
  const SineTrajectory sine(options.backlash_amplitude_mm, options.backlash_frequency_hz);
  ServoLoop loop(hardware, servo);
  NoCompensation none;
  const double period = 1.0 / options.backlash_frequency_hz;
  const std::vector<CycleRecord> records =
      RunFixedStep(loop, sine, none, period * options.backlash_cycles);
  std::vector<double> t;
  std::vector<double> base;
  std::vector<double> tip;
  for (const CycleRecord& r : records) {
    if (r.t_s < period) continue;
    t.push_back(r.t_s);
    base.push_back(r.base_mm);
    tip.push_back(r.tip_mm);
  }
  return EstimateHysteresisWidth(t, base, tip);
}

CalibrationResult Calibrate(hw::HardwareInterface& hardware, const ServoConfig& servo,
                            const ProbeOptions& options) {
  CalibrationResult result;
  result.friction_samples = ProbeFriction(hardware, servo, options);
  result.friction = FitCoulombViscous(result.friction_samples);
  result.backlash = ProbeBacklash(hardware, servo, options);
  return result;
}

}  // namespace echoservo::control
