// The measurement-noise floor of a target-motion trace, estimated from the trace alone:
// the σ (mm) that normalises every motion-lab residual, independent of the model SPEC so
// that an effect the model lacks shows up as excess instead of inflating the noise.
//
// Two model-free estimates; the lab uses the smaller. Each equals σ for white noise and
// can only be inflated by signal (a signal adds variance, it never removes noise), so the
// smaller is the tighter bound:
//   differences: min over orders k = 2..6 of 1.4826·MAD(Δᵏx)/√C(2k,k) (Var Δᵏe =
//     C(2k,k)σ² for white e). Slow effects (drift, respiration, amplitude modulation) and
//     the heartbeat's low harmonics are suppressed by (2 sin(πf/fs))ᵏ; the best order
//     depends on the spectrum, hence the minimum. Fails when the heartbeat has strong
//     harmonics near the Nyquist rate (e.g. 3.7 Hz at 25 Hz sampling: harmonics at 7.4,
//     11.1 Hz are amplified, not suppressed).
//   local heartbeat: the trace is cut into windows of max(3 s, 3 beats); each window gets
//     its own Fourier heartbeat (rate searched within ±25 % of the trace's rate, harmonic
//     count by BIC, estimation/harmonic_fit.h) plus a quadratic in time; σ is the median
//     over windows of the residual RMS corrected for the fitted parameters. A slow effect
//     is nearly a constant + slope + curvature within a window, so it is absorbed; fast
//     harmonics are modelled. Inflated by beat-to-beat variability within a window.
// Sampling: uniform sampling is assumed for the differences (a gap only spoils a few
// differences, which the MAD ignores). Floor: max(quantum/√12, 1 µm).
// Details: docs/model_lab.md#motion-noise-labmotion_noiseh
#pragma once

#include <vector>

#include "estimation/motion_trace.h"

namespace echoservo::lab {

struct MotionNoise {
  double position_mm = 0.0;    // the lab's σ: min(difference_mm, local_fit_mm), floored
  double difference_mm = 0.0;  // best difference order
  int difference_order = 0;    // the k that gave it
  double local_fit_mm = 0.0;   // median windowed heartbeat residual (inf: no window fitted)
  double rate_hz = 0.0;        // the trace's heart rate (middle third)
  // Local heart rate (bpm) at every sample, from the windowed fits (linear between window
  // centres; the trace's rate where no window was fitted).
  std::vector<double> local_rate_bpm;
};

// Throws std::invalid_argument (naming the trace) for a trace shorter than two beats at
// 36 bpm (3.3 s) or with fewer than 16 samples.
MotionNoise EstimateMotionNoise(const estimation::MotionTrace& trace);

}  // namespace echoservo::lab
