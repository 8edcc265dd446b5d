// Reference trajectories for the catheter tip (mm along the catheter axis, s).
//
// `SineTrajectory` is the seed's 1 Hz test motion. `MitralTrajectory` is a documented
// multi-harmonic model of the human mitral annulus along the ventricle's long axis
// (docs/mitral_trajectory.md): a systolic excursion towards the apex, a fast early-
// diastolic return, diastasis and an atrial kick, built from keyframes and truncated
// to 10 harmonics; at 75 bpm and 15 mm peak to peak it peaks near 160 mm/s and
// 3600 mm/s². Trajectories are known ahead of time, so compensators may look ahead.
#pragma once

#include <memory>
#include <string>

#include "estimation/fourier_motion.h"

namespace echoservo::control {

using estimation::MotionSample;

class Trajectory {
 public:
  virtual ~Trajectory() = default;
  virtual MotionSample Evaluate(double t_s) const = 0;
  virtual std::string name() const = 0;
};

class SineTrajectory final : public Trajectory {
 public:
  // Throws std::invalid_argument for non-finite or non-positive amplitude/frequency.
  SineTrajectory(double amplitude_mm, double frequency_hz);
  MotionSample Evaluate(double t_s) const override;
  std::string name() const override { return "sine"; }

 private:
  double amplitude_mm_;
  double frequency_hz_;
};

// Constant-speed triangle wave between ±amplitude (the probing motion of calibration
// and of the friction experiment); starts at 0 moving up.
class TriangleTrajectory final : public Trajectory {
 public:
  // Throws std::invalid_argument for non-finite or non-positive amplitude/speed.
  TriangleTrajectory(double amplitude_mm, double speed_mm_s);
  MotionSample Evaluate(double t_s) const override;
  std::string name() const override { return "triangle"; }
  double period_s() const { return 4.0 * amplitude_mm_ / speed_mm_s_; }

 private:
  double amplitude_mm_;
  double speed_mm_s_;
};

struct MitralOptions {
  double heart_rate_bpm = 75.0;
  double peak_to_peak_mm = 15.0;
  int harmonics = 10;
};

class MitralTrajectory final : public Trajectory {
 public:
  // Throws std::invalid_argument outside 30–200 bpm, 1–40 mm, 1–30 harmonics.
  explicit MitralTrajectory(MitralOptions options = {});
  MotionSample Evaluate(double t_s) const override { return motion_.Evaluate(t_s); }
  std::string name() const override { return "mitral"; }
  const estimation::FourierMotion& motion() const { return motion_; }

 private:
  estimation::FourierMotion motion_;
};

// Builds a trajectory from a spec: "sine" (5 mm, 1 Hz), "sine:AMP_MM:FREQ_HZ",
// "triangle:AMP_MM:SPEED_MM_S", "mitral" (75 bpm, 15 mm) or "mitral:BPM:P2P_MM".
// Throws std::invalid_argument naming the spec and the bad field.
std::unique_ptr<Trajectory> MakeTrajectory(const std::string& spec);

}  // namespace echoservo::control
