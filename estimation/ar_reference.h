// The best simple predictor, as a yardstick: an autoregressive direct predictor fitted
// offline by least squares on the first half of a trace, its order chosen by blocked
// cross-validation on that half, and scored on the second half. `echoservo predict`
// reports it as `reference`, beside what ships scored on the same second half.
//
// In: measurements (s, mm), at a roughly constant rate, and the latency L (s). Model, on
// the measurement index n with lags spaced `stride` samples apart (stride = ⌈rate /
// max_lag_rate_hz⌉: lags at ≤ 50 Hz, so an order covers a heartbeat with ≤ 90
// parameters): x(t_n + L) − x_n = w₀ + Σ_{i=1..p−1} wᵢ (x_{n−i·stride} − x_n) — the
// offset-free form of the online predictor (estimation/ar_predictor.h); w = 0 is the
// zero-order hold. The target x(t_n + L) is the measurements linearly interpolated there
// (never across a gap). Rows whose lags or target cross a gap (an interval > 1.6 × the
// median) are skipped; where the history is broken in the scored half, the reference
// holds the newest measurement (counted in `held`).
// Split: t_mid = the middle of the measurements' span; training rows have their target at
// or before t_mid, scored instants are measurements at or after t_mid. Order: the
// candidates kArCandidateOrders (below) up to max_history_s of
// lags and a tenth of the training rows (kArRowsPerParameter), each scored by 5-fold blocked
// cross-validation (training rows within the order's reach of the held-out block left out); the
// lowest summed squared validation error wins. Ridge kArRidge × the Gram's mean diagonal. Errors:
// FitArReference throws std::invalid_argument for a trace too short for the split (each half must
// span min_half_s and hold the rows the smallest order needs; the message says how long the trace
// must be) or bad options. Details:
// docs/predictor.md#the-autoregressive-reference-estimationar_referenceh
#pragma once

#include <cstddef>
#include <vector>

#include "estimation/motion_trace.h"

namespace echoservo::estimation {

// The candidate orders (parameters, the offset included), up to the longest lag span allowed.
inline constexpr int kArCandidateOrders[] = {1, 2, 3, 4, 6, 8, 11, 16, 22, 32, 45, 64, 90};
// A candidate is used only with at least this many training rows per parameter.
inline constexpr int kArRowsPerParameter = 10;
// Ridge, relative to the Gram's mean diagonal (noise-free periodic motion over many lags is
// ill-conditioned without it).
inline constexpr double kArRidge = 1e-6;

struct ArReferenceOptions {
  double latency_s = 0.1;
  double max_history_s = 2.0;     // the longest lag span a candidate order may have
  double max_lag_rate_hz = 50.0;  // lags no denser than this (stride)
  double min_half_s = 4.0;        // each half spans at least this
  int folds = 5;
};

struct ArReference {
  int order = 0;                          // p (parameters, the offset included)
  int stride = 1;                         // samples between lags
  double history_s = 0.0;                 // (p − 1) × stride × the median interval
  double split_s = 0.0;                   // t_mid: fitted before, scored from
  std::size_t trained = 0;                // training rows
  std::size_t scored = 0;                 // scored instants (second half)
  std::size_t held = 0;                   // of them, predicted by holding (history broken by a gap)
  std::vector<int> candidates;            // orders tried
  std::vector<double> validation_rms_mm;  // their cross-validated RMS
  std::vector<double> weights;            // w₀ … w_{p−1}
  // The scored instants and predictions (x at t + L), in order.
  std::vector<double> t_s;
  std::vector<double> predicted_mm;
};

// Fits on `measured` (first half) and predicts at each second-half measurement. Throws
// std::invalid_argument (see the file comment).
ArReference FitArReference(const MotionTrace& measured, const ArReferenceOptions& options);

// The shortest trace span (s) FitArReference accepts at a measurement rate (Hz).
double ArReferenceMinimumSpan(const ArReferenceOptions& options, double rate_hz);

}  // namespace echoservo::estimation
