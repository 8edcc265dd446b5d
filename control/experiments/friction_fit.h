// Fit of the seed's friction law F(v) = F_c·sign(v) + b·v to force–velocity samples.
//
// Samples are (mean base velocity in mm/s, mean force-sensor reading in N) from
// constant-velocity strokes; the fit is a bounded least-squares problem solved with
// Ceres (F_c ≥ 0, b ≥ 0), with standard deviations from ceres::Covariance scaled by
// the residual variance, the RMS residual (N) and r².
#pragma once

#include <vector>

namespace echoservo::control {

struct FrictionSample {
  double velocity_mm_s = 0.0;
  double force_n = 0.0;
};

struct FrictionFit {
  double coulomb_n = 0.0;
  double viscous_n_per_mm_s = 0.0;
  double coulomb_sd_n = 0.0;
  double viscous_sd_n_per_mm_s = 0.0;
  double rms_n = 0.0;
  double r2 = 0.0;
};

// Throws std::invalid_argument with fewer than 3 samples, non-finite values, or no
// sample in one of the two directions.
FrictionFit FitCoulombViscous(const std::vector<FrictionSample>& samples);

}  // namespace echoservo::control
