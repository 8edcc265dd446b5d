// Realistic beating-heart traces: a generator of target motion with the irregularities of
// real recordings, independent of the smooth synthetic mitral trace
// (control/experiments/synthetic_motion.h): it shares no code with it and builds motion
// beat by beat instead of from a phase.
//
// Each beat gets its own duration (RR interval) from a heart rate with a slow
// Ornstein–Uhlenbeck wander, respiratory sinus arrhythmia, a rate step and a linear drift;
// ectopic (premature) beats come early (0.65 RR, weaker) and are followed by a
// compensatory pause (1.35 RR, stronger), so the next normal beat keeps the sinus timing.
// Within a beat the wall contracts over a systole whose duration grows with √RR and
// relaxes exponentially in diastole, with an atrial kick before the next beat. Breathing
// (irregular rate) shifts the baseline and modulates the beat's amplitude. Noise is
// Student-t (heavy-tailed), plus sparse outliers; samples are dropped singly and in
// bursts. Units: s, Hz, bpm, mm. Deterministic for a seed (std::mt19937_64).
// Errors: GenerateRealisticHeartTrace throws std::invalid_argument for bad options;
// RealisticHeartClass for an unknown class name (listing the known ones).
// Details: docs/predictor.md#realistic-traces-estimationrealistic_heart_traceh
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "estimation/motion_trace.h"

namespace echoservo::estimation {

struct RealisticHeartOptions {
  double duration_s = 30.0;
  double sample_rate_hz = 25.0;
  double heart_bpm = 72.0;
  double hrv_bpm = 3.0;        // σ of the slow wander (τ 10 s)
  double rsa_bpm = 2.0;        // respiratory sinus arrhythmia amplitude
  double rate_step_bpm = 0.0;  // added at rate_step_at_s
  double rate_step_at_s = 15.0;
  double rate_drift_bpm_per_min = 0.0;
  double ectopic_probability = 0.0;   // per beat
  double amplitude_mm = 8.0;          // contraction peak to peak
  double breathing_hz = 0.25;         // mean breathing rate (breath-to-breath ±15 %)
  double breathing_mm = 1.0;          // baseline peak to peak
  double breathing_modulation = 0.1;  // fractional amplitude modulation of the beats
  double noise_mm = 0.15;             // scale of the Student-t noise
  double noise_dof = 3.0;             // its degrees of freedom (heavy tails)
  double outlier_probability = 0.005;
  double outlier_mm = 4.0;
  double drop_probability = 0.01;    // single dropped samples
  double burst_probability = 0.002;  // a burst of 3–8 dropped samples starts here
  std::uint64_t seed = 1;
};

// The measured trace (column "position"); `truth` (optional) receives the noise-free
// motion at every sample, dropped ones included (column "truth").
MotionTrace GenerateRealisticHeartTrace(const RealisticHeartOptions& options,
                                        MotionTrace* truth = nullptr);

// Named classes: regular, ectopic, rate_steps, breathing, noisy, sparse, fast.
std::vector<std::string> RealisticHeartClasses();
RealisticHeartOptions RealisticHeartClass(const std::string& name, std::uint64_t seed = 1);

}  // namespace echoservo::estimation
