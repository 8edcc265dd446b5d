// The heart rate of a motion trace from its fundamental: what the heartbeat EKF acquires
// its rate from and what `echoservo predict` reports, built so that it cannot lock onto a
// sub-harmonic (half the rate) or a harmonic (twice or three times it) of the beat, and
// says "none" rather than a wrong figure when the trace holds no significant heartbeat.
//
// In: positions (mm) at times (s, strictly increasing), any roughly constant rate (resampled
// to a uniform grid at ≤ max_analysis_hz, by block means above it). Method: quadratic
// detrend; the amplitude spectrum A²(f) = (2/n)²|Σ y e^{−i2πft}|² on a grid 4× finer than
// 1/span; the harmonic sum HS(f₀) = Σ_{k≤K} A²(k f₀) over the band; its best f₀ refined by
// golden section on exact sums; then the checks, by nested harmonic regressions (which
// spectral leakage cannot fool): f₀ is a sub-harmonic (doubled) when its odd harmonics add
// nothing significant to the model of 2f₀; f₀/3 or f₀/2 inside the band is the fundamental
// (f₀ was a harmonic) when its harmonics between f₀'s add something significant (F-tests at
// false_alarm); and by the autocorrelation: a motion that repeats at half the candidate's
// period (≥ 0.8 × as well) has twice its rate. A candidate within half a resolution bin
// of a multiple of the strongest line below the band, when that line is stronger than f₀
// and adds significantly, is a harmonic of a slower motion (respiration): no heart rate.
// Significance of the result: the harmonic regression at f₀ (K harmonics, quadratic trend) beats
// the trend alone in an F-test whose family-wise p over the band's independent frequencies is below
// false_alarm, AND the autocorrelation agrees: on the trace less its moving average over one period
// (what is slower than the beat removed), its maximum over lags [0.6, 1.4]/f₀ lies within ±15 % of
// 1/f₀ and is at least min_repeat_correlation (the motion repeats beat to beat).
// Out: HeartRateEstimate; rate_hz is the best candidate even when not significant (reason
// says why it is not). Bounded: rate_hz ∈ [min_hz, max_hz] always.
// Errors: EstimateHeartRate throws std::invalid_argument for inconsistent options, fewer
// than 16 samples, non-finite values or non-increasing times.
// Details: docs/predictor.md#the-heart-rate-estimationheart_rateh
#pragma once

#include <cstddef>
#include <string>

namespace echoservo::estimation {

struct HeartRateOptions {
  double min_hz = 0.5;  // 30 bpm
  double max_hz = 3.5;  // 210 bpm
  int harmonics = 5;    // K of the harmonic sum and of the regression
  double false_alarm = 1e-3;
  double max_analysis_hz = 40.0;        // the uniform grid's rate at most
  double min_repeat_correlation = 0.6;  // autocorrelation at the period
};

struct HeartRateEstimate {
  bool significant = false;
  double rate_hz = 0.0;  // the best candidate (see `significant`)
  double bpm() const { return 60.0 * rate_hz; }
  double p_value = 1.0;  // family-wise, of the F-test
  double f_statistic = 0.0;
  double acf_period_s = 0.0;   // the autocorrelation's peak lag near 1/rate
  double acf_at_period = 0.0;  // its value there (−1 … 1)
  bool acf_agrees = false;
  double fundamental_share = 0.0;  // A²(f₀) / HS(f₀)
  int corrections = 0;             // sub-harmonic or harmonic corrections applied
  std::string reason;              // why (not) significant, with the figures
};

HeartRateEstimate EstimateHeartRate(const double* t_s, const double* x_mm, std::size_t n,
                                    const HeartRateOptions& options = {});

}  // namespace echoservo::estimation
