#include "lab/model_fit.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <numeric>
#include <stdexcept>

namespace echoservo::lab {
namespace {

// Residuals of one trial: tip then force, on the trial's fit samples, normalised.
class TrialResidual {
 public:
  TrialResidual(hw::TransmissionModel model, const LabTrial* trial, NoiseLevels noise,
                const double* fixed_parameters)
      : model_(std::move(model)), trial_(trial), noise_(noise), fixed_(fixed_parameters) {}

  int num_residuals() const { return static_cast<int>(2 * trial_->fit_index.size()); }
  std::size_t num_parameters() const { return model_.parameters().size(); }

  // Blocks: [physical (if any and not fixed)], offset, contact.
  bool operator()(double const* const* blocks, double* residuals) const {
    std::size_t b = 0;
    if (num_parameters() > 0) model_.SetParametersForFit(fixed_ != nullptr ? fixed_ : blocks[b++]);
    const TrialNuisance nuisance{blocks[b][0], blocks[b + 1][0]};
    PredictTrial(model_, *trial_, nuisance, prediction_);
    const std::size_t m = trial_->fit_index.size();
    for (std::size_t r = 0; r < m; ++r) {
      const std::size_t i = trial_->fit_index[r];
      residuals[r] = (prediction_.tip_mm[i] - trial_->trial.tip_mm[i]) / noise_.tip_mm;
      residuals[m + r] = (prediction_.force_n[i] - trial_->trial.force_n[i]) / noise_.force_n;
    }
    return std::all_of(residuals, residuals + 2 * m, [](double v) { return std::isfinite(v); });
  }

 private:
  mutable hw::TransmissionModel model_;
  const LabTrial* trial_;
  NoiseLevels noise_;
  const double* fixed_;
  mutable Prediction prediction_;
};

class ProgressCallback : public ceres::IterationCallback {
 public:
  ProgressCallback(const FitOptions& o, std::string what)
      : options_(o), what_(std::move(what)), start_(std::chrono::steady_clock::now()) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (options_.progress && elapsed > 1.0) {
      options_.progress(what_ + ": iteration " + std::to_string(s.iteration) + ", cost " +
                        std::to_string(s.cost) + ", " + std::to_string(static_cast<int>(elapsed)) +
                        " s");
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const FitOptions& options_;
  std::string what_;
  std::chrono::steady_clock::time_point start_;
};

std::vector<std::size_t> AllTrials(const LabDataset& ds, const std::vector<std::size_t>& subset) {
  if (!subset.empty()) return subset;
  std::vector<std::size_t> all(ds.trials.size());
  std::iota(all.begin(), all.end(), 0);
  return all;
}

FitResult Run(const std::vector<std::string>& effects, const LabDataset& ds,
              const FitOptions& options, const std::vector<std::size_t>& subset_in,
              const std::vector<double>* start, bool fix_physical) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<std::size_t> subset = AllTrials(ds, subset_in);
  if (subset.empty()) throw std::invalid_argument("lab fit: no trial to fit");
  const hw::EffectRegistry& registry = FitCatalog(options);
  hw::TransmissionModel prototype(registry, effects, ds.trials[subset.front()].trial.config);

  FitResult result;
  result.effects = effects;
  result.parameters = prototype.parameters();
  if (start != nullptr) {
    if (start->size() != result.parameters.size())
      throw std::invalid_argument("lab fit: wrong number of initial values");
    result.parameters = *start;
  }
  const std::size_t np = result.parameters.size();
  std::vector<double> offsets(subset.size(), 0.0);
  std::vector<double> contacts(subset.size(), 0.0);

  ceres::Problem::Options problem_options;
  ceres::Problem problem(problem_options);
  double* physical = np > 0 ? result.parameters.data() : nullptr;
  const bool has_width = prototype.BacklashWidthMm() > 0.0 || prototype.HasEffect("backlash") ||
                         prototype.HasEffect("friction_backlash");
  for (std::size_t k = 0; k < subset.size(); ++k) {
    const LabTrial& lt = ds.trials[subset[k]];
    hw::TransmissionModel model(registry, effects, lt.trial.config);
    // Start the offset at the mean tip-vs-base difference (fast convergence).
    double mean = 0.0;
    for (std::size_t i = 0; i < lt.trial.size(); ++i)
      mean += lt.trial.tip_mm[i] - lt.trial.base_mm[i];
    offsets[k] = mean / static_cast<double>(lt.trial.size());
    auto* functor =
        new TrialResidual(std::move(model), &lt, ds.noise, fix_physical ? physical : nullptr);
    auto* cost = new ceres::DynamicNumericDiffCostFunction<TrialResidual, ceres::CENTRAL>(
        functor, ceres::TAKE_OWNERSHIP);
    std::vector<double*> blocks;
    if (np > 0 && !fix_physical) {
      cost->AddParameterBlock(static_cast<int>(np));
      blocks.push_back(physical);
    }
    cost->AddParameterBlock(1);
    cost->AddParameterBlock(1);
    blocks.push_back(&offsets[k]);
    blocks.push_back(&contacts[k]);
    cost->SetNumResiduals(functor->num_residuals());
    problem.AddResidualBlock(cost, nullptr, blocks);
    problem.SetParameterLowerBound(&contacts[k], 0, -1.0);
    problem.SetParameterUpperBound(&contacts[k], 0, 1.0);
    if (!has_width) problem.SetParameterBlockConstant(&contacts[k]);
  }
  if (np > 0 && !fix_physical) {
    for (std::size_t i = 0; i < np; ++i) {
      const hw::ParameterSpec& s = prototype.parameter_info()[i].spec;
      result.parameters[i] = std::clamp(result.parameters[i], s.lower, s.upper);
      problem.SetParameterLowerBound(physical, static_cast<int>(i), s.lower);
      problem.SetParameterUpperBound(physical, static_cast<int>(i), s.upper);
    }
  }

  ceres::Solver::Options so;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = std::max(1, options.threads);
  so.linear_solver_type = ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)
                              ? ceres::SPARSE_NORMAL_CHOLESKY
                              : ceres::DENSE_QR;
  so.function_tolerance = 1e-7;
  so.logging_type = ceres::SILENT;
  ProgressCallback progress(options, "fit " + hw::FormatModelSpec(effects));
  if (options.progress) so.callbacks.push_back(&progress);
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  result.iterations = static_cast<int>(summary.iterations.size());

  // Covariance of the physical parameters, scaled by the reduced chi-square.
  prototype.SetParametersForFit(result.parameters.data());
  for (std::size_t i = 0; i < np; ++i) {
    result.estimates.push_back({prototype.parameter_info()[i].qualified_name,
                                prototype.parameter_info()[i].spec.unit, result.parameters[i],
                                std::nan("")});
  }
  if (np > 0 && !fix_physical) {
    ceres::Covariance::Options co;
    // Sparse QR on the block-sparse Jacobian (each trial's rows touch only its own
    // nuisance): the physical parameters' covariance marginalised over the nuisance.
    // A dense SVD would materialise residuals × all parameters. A rank-deficient fit
    // (an unidentifiable parameter) leaves the standard deviations undefined (NaN).
    co.algorithm_type = ceres::SPARSE_QR;
    ceres::Covariance covariance(co);
    const std::vector<std::pair<const double*, const double*>> block = {{physical, physical}};
    if (covariance.Compute(block, &problem)) {
      std::vector<double> c(np * np);
      covariance.GetCovarianceBlock(physical, physical, c.data());
      const double dof = std::max(
          1.0, static_cast<double>(summary.num_residuals - summary.num_effective_parameters));
      const double chi2 = 2.0 * summary.final_cost / dof;
      for (std::size_t i = 0; i < np; ++i)
        result.estimates[i].sd = std::sqrt(std::max(c[i * np + i] * chi2, 0.0));
    }
  }

  // Full-rate residual statistics.
  double tip_ss = 0.0, tip_abs = 0.0, force_ss = 0.0, fit_tip_ss = 0.0, fit_force_ss = 0.0;
  std::size_t n_all = 0, n_fit = 0;
  for (std::size_t k = 0; k < subset.size(); ++k) {
    const LabTrial& lt = ds.trials[subset[k]];
    hw::TransmissionModel model(registry, effects, lt.trial.config);
    if (np > 0) model.SetParametersForFit(result.parameters.data());
    TrialResult tr;
    tr.name = lt.trial.name;
    tr.nuisance = {offsets[k], contacts[k]};
    PredictTrial(model, lt, tr.nuisance, tr.prediction);
    double t_ss = 0.0, t_abs = 0.0, f_ss = 0.0;
    for (std::size_t i = 0; i < lt.trial.size(); ++i) {
      const double et = tr.prediction.tip_mm[i] - lt.trial.tip_mm[i];
      const double ef = tr.prediction.force_n[i] - lt.trial.force_n[i];
      t_ss += et * et;
      t_abs += std::abs(et);
      f_ss += ef * ef;
      tr.stats.tip_max_mm = std::max(tr.stats.tip_max_mm, std::abs(et));
    }
    for (std::size_t i : lt.fit_index) {
      fit_tip_ss += std::pow((tr.prediction.tip_mm[i] - lt.trial.tip_mm[i]) / ds.noise.tip_mm, 2);
      fit_force_ss +=
          std::pow((tr.prediction.force_n[i] - lt.trial.force_n[i]) / ds.noise.force_n, 2);
    }
    const auto n = static_cast<double>(lt.trial.size());
    tr.stats.samples = lt.trial.size();
    tr.stats.tip_rms_mm = std::sqrt(t_ss / n);
    tr.stats.tip_mae_mm = t_abs / n;
    tr.stats.force_rms_n = std::sqrt(f_ss / n);
    tip_ss += t_ss;
    tip_abs += t_abs;
    force_ss += f_ss;
    n_all += lt.trial.size();
    n_fit += lt.fit_index.size();
    result.overall.tip_max_mm = std::max(result.overall.tip_max_mm, tr.stats.tip_max_mm);
    result.trials.push_back(std::move(tr));
  }
  result.overall.samples = n_all;
  result.overall.tip_rms_mm = std::sqrt(tip_ss / static_cast<double>(n_all));
  result.overall.tip_mae_mm = tip_abs / static_cast<double>(n_all);
  result.overall.force_rms_n = std::sqrt(force_ss / static_cast<double>(n_all));
  result.tip_mse_norm = fit_tip_ss / static_cast<double>(n_fit);
  result.force_mse_norm = fit_force_ss / static_cast<double>(n_fit);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace

FitResult FitModel(const std::vector<std::string>& effects, const LabDataset& dataset,
                   const FitOptions& options, const std::vector<std::size_t>& subset,
                   const std::vector<double>* initial) {
  return Run(effects, dataset, options, subset, initial, false);
}

FitResult EvaluateModel(const std::vector<std::string>& effects,
                        const std::vector<double>& parameters, const LabDataset& dataset,
                        const FitOptions& options, const std::vector<std::size_t>& subset) {
  return Run(effects, dataset, options, subset, &parameters, true);
}

const hw::EffectRegistry& FitCatalog(const FitOptions& o) {
  static const hw::EffectRegistry builtin = hw::EffectRegistry::WithBuiltinEffects();
  return o.registry != nullptr ? *o.registry : builtin;
}

}  // namespace echoservo::lab
