#include "control/experiments/friction_fit.h"

#include <ceres/ceres.h>

#include <cmath>
#include <stdexcept>

namespace echoservo::control {
namespace {

struct FrictionResidual {
  double v;
  double f;
  template <typename T>
  bool operator()(const T* const p, T* residual) const {
    const double s = v > 0.0 ? 1.0 : -1.0;
    residual[0] = T(f) - (p[0] * s + p[1] * v);
    return true;
  }
};

}  // namespace

FrictionFit FitCoulombViscous(const std::vector<FrictionSample>& samples) {
  if (samples.size() < 3) throw std::invalid_argument("friction fit: need at least 3 samples");
  bool up = false;
  bool down = false;
  double mean_f = 0.0;
  for (const FrictionSample& s : samples) {
    if (!std::isfinite(s.velocity_mm_s) || !std::isfinite(s.force_n)) {
      throw std::invalid_argument("friction fit: non-finite sample");
    }
    up = up || s.velocity_mm_s > 0.0;
    down = down || s.velocity_mm_s < 0.0;
    mean_f += s.force_n / static_cast<double>(samples.size());
  }
  if (!up || !down) throw std::invalid_argument("friction fit: need samples in both directions");

  double p[2] = {0.5, 0.005};
  ceres::Problem problem;
  for (const FrictionSample& s : samples) {
    if (s.velocity_mm_s == 0.0) continue;
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<FrictionResidual, 1, 2>(
                                 new FrictionResidual{s.velocity_mm_s, s.force_n}),
                             nullptr, p);
  }
  problem.SetParameterLowerBound(p, 0, 0.0);
  problem.SetParameterLowerBound(p, 1, 0.0);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 100;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);

  FrictionFit fit;
  fit.coulomb_n = p[0];
  fit.viscous_n_per_mm_s = p[1];
  double ss_res = 0.0;
  double ss_tot = 0.0;
  for (const FrictionSample& s : samples) {
    const double model = p[0] * (s.velocity_mm_s > 0.0 ? 1.0 : -1.0) + p[1] * s.velocity_mm_s;
    ss_res += (s.force_n - model) * (s.force_n - model);
    ss_tot += (s.force_n - mean_f) * (s.force_n - mean_f);
  }
  const auto n = static_cast<double>(samples.size());
  fit.rms_n = std::sqrt(ss_res / n);
  fit.r2 = ss_tot > 0.0 ? 1.0 - ss_res / ss_tot : 1.0;

  ceres::Covariance::Options cov_options;
  cov_options.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance covariance(cov_options);
  const std::vector<std::pair<const double*, const double*>> blocks = {{p, p}};
  if (samples.size() > 2 && covariance.Compute(blocks, &problem)) {
    double c[4];
    covariance.GetCovarianceBlock(p, p, c);
    // Ceres returns (JᵀJ)⁻¹; scale by the residual variance σ² = SS/(n − 2).
    const double sigma2 = ss_res / (n - 2.0);
    fit.coulomb_sd_n = std::sqrt(std::max(c[0] * sigma2, 0.0));
    fit.viscous_sd_n_per_mm_s = std::sqrt(std::max(c[3] * sigma2, 0.0));
  }
  return fit;
}

}  // namespace echoservo::control
