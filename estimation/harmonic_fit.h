// Batch fit of a heartbeat (a Fourier series of unknown rate) to a window of samples: the
// initialisation of the heartbeat EKF (estimation/heartbeat_ekf.h) and the starting point of
// the motion lab's fits (lab/motion_model.h).
//
// In: sample times t_s (s) and positions x_mm (mm), a reference time t_ref_s, rates in Hz.
// Out: the rate and harmonic count chosen by BIC, and a FourierMotion referred to t_ref,
// phase-normalised (the fundamental's sine coefficient 0, its cosine coefficient ≥ 0).
// Errors: FitHarmonics throws std::invalid_argument (cases on its declaration).
// Details: docs/predictor.md#the-batch-heartbeat-fit-estimationharmonic_fith
#pragma once

#include <cstddef>

#include "estimation/fourier_motion.h"

namespace echoservo::estimation {

struct HarmonicFitOptions {
  double min_rate_hz = 0.6;  // 36 bpm
  double max_rate_hz = 3.0;  // 180 bpm
  int harmonics = 0;         // 0: automatic (BIC), up to max_harmonics
  int max_harmonics = 8;
  // Order of the polynomial in time fitted beside the harmonics (0: a constant offset;
  // 1: a linear trend; up to 3), which absorbs slow respiration within the window.
  int trend_order = 1;
  // > 0: choose the harmonic count (BIC) and estimate the noise on the newest this many
  // beats at the found rate, where heart-rate variability blurs the higher harmonics
  // less than over the whole window; the coefficients still come from the whole window.
  double shape_window_beats = 0.0;
};

struct HarmonicFit {
  // t0_s = t_ref; phase0_rad the phase at t_ref; offset_mm and drift_mm_s the value and
  // slope of the fitted polynomial at t_ref (drift 0 for order 0).
  FourierMotion motion;
  int harmonics = 0;
  double residual_rms_mm = 0.0;
  double noise_mm = 0.0;  // residual RMS corrected for the fitted parameters
  std::size_t samples = 0;
};

// Throws std::invalid_argument when the window is too short for one beat at
// min_rate_hz, has fewer samples than parameters, or the options are inconsistent.
HarmonicFit FitHarmonics(const double* t_s, const double* x_mm, std::size_t n, double t_ref_s,
                         const HarmonicFitOptions& options);

// Least-squares coefficients at a fixed rate (no search); same normalisation.
HarmonicFit FitHarmonicsAtRate(const double* t_s, const double* x_mm, std::size_t n, double t_ref_s,
                               double rate_hz, int harmonics, int trend_order);

}  // namespace echoservo::estimation
