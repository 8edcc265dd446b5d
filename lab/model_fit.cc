#include "lab/model_fit.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <memory>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include "lab/smooth_shape.h"

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
    // An effect that refuses the step's values (a tabulated term's input pushed outside its
    // knots by a trial parameter) fails this evaluation: Ceres then tries a shorter step.
    // Its error never crosses Ceres' worker threads; the data's own range is checked before
    // the solve (Run), where the error reaches the user.
    try {
      PredictTrial(model_, *trial_, nuisance, prediction_);
    } catch (const std::exception&) {
      return false;
    }
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

// Second differences of a block of knot values (SmoothnessPenalty) as residuals.
class SmoothnessResidual : public ceres::CostFunction {
 public:
  SmoothnessResidual(std::size_t parameters, std::size_t first, std::size_t n0, std::size_t n1,
                     double weight)
      : weight_(weight) {
    auto at = [&](std::size_t i, std::size_t j) { return first + i * n1 + j; };
    for (std::size_t j = 0; j < n1; ++j)
      for (std::size_t i = 1; i + 1 < n0; ++i)
        triples_.push_back({at(i - 1, j), at(i, j), at(i + 1, j)});
    for (std::size_t i = 0; i < n0; ++i)
      for (std::size_t j = 1; j + 1 < n1; ++j)
        triples_.push_back({at(i, j - 1), at(i, j), at(i, j + 1)});
    set_num_residuals(static_cast<int>(triples_.size()));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(parameters));
    parameters_ = parameters;
  }
  bool empty() const { return triples_.empty(); }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    const double* v = p[0];
    for (std::size_t r = 0; r < triples_.size(); ++r) {
      const auto& [a, b, c] = triples_[r];
      residuals[r] = weight_ * (v[a] - 2.0 * v[b] + v[c]);
    }
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      std::fill(jacobians[0], jacobians[0] + triples_.size() * parameters_, 0.0);
      for (std::size_t r = 0; r < triples_.size(); ++r) {
        const auto& [a, b, c] = triples_[r];
        jacobians[0][r * parameters_ + a] = weight_;
        jacobians[0][r * parameters_ + b] = -2.0 * weight_;
        jacobians[0][r * parameters_ + c] = weight_;
      }
    }
    return true;
  }

 private:
  struct Triple {
    std::size_t a, b, c;
  };
  std::vector<Triple> triples_;
  std::size_t parameters_ = 0;
  double weight_;
};

// The value of a table input at sample i of a trial, when it is one of the trial's own
// signals or its geometry; false otherwise (the model's tip, its friction force).
bool SignalInput(const LabTrial& lt, const std::string& input, std::size_t i, double& out) {
  const formats::Trial& tr = lt.trial;
  if (input == "time_s")
    out = tr.t_s[i] - tr.t_s.front();
  else if (input == "base_mm")
    out = tr.base_mm[i];
  else if (input == "velocity_mm_s")
    out = lt.velocity_mm_s[i];
  else if (input == "speed_mm_s")
    out = std::abs(lt.velocity_mm_s[i]);
  else if (input == "acceleration_mm_s2")
    out = lt.acceleration_mm_s2[i];
  else if (input == "bend_rad")
    out = tr.config.TotalBendRad();
  else if (input == "bend_deg")
    out = tr.config.TotalBendRad() * 180.0 / std::numbers::pi;
  else if (input == "gap_mm")
    out = tr.config.GapMm();
  else if (input == "tip_load_n")
    out = tr.config.tip_load_n;
  else
    return false;
  return true;
}

// A local table block of one trial: where its values sit among the physical parameters and
// each fit sample's hat functions (TabulatedBlock).
struct LocalTable {
  std::size_t first = 0;
  std::size_t size = 0;
  std::vector<std::array<std::size_t, 4>> columns;  // per fit sample
  std::vector<std::array<double, 4>> weights;
  std::vector<int> count;
};

// A trial's residuals with the Jacobian computed column by column by central differences
// (as ceres::CENTRAL does), except the tip offset's (exact: 1/σ on the tip rows) and the
// local tables' (one directional derivative each, TabulatedBlock).
class TableTrialCost : public ceres::CostFunction {
 public:
  TableTrialCost(TrialResidual* functor, std::size_t np, bool fixed, std::vector<LocalTable> tables,
                 double tip_noise)
      : functor_(functor), np_(fixed ? 0 : np), tables_(std::move(tables)), tip_noise_(tip_noise) {
    set_num_residuals(functor_->num_residuals());
    if (np_ > 0) mutable_parameter_block_sizes()->push_back(static_cast<int>(np_));
    mutable_parameter_block_sizes()->push_back(1);
    mutable_parameter_block_sizes()->push_back(1);
  }

  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    if (!(*functor_)(p, residuals)) return false;
    if (jacobians == nullptr) return true;
    const auto m = static_cast<std::size_t>(num_residuals());
    std::vector<double> physical(p[0], p[0] + np_);
    double offset = p[np_ > 0 ? 1 : 0][0];
    double contact = p[np_ > 0 ? 2 : 1][0];
    std::vector<double> plus(m), minus(m);
    auto run = [&](std::vector<double>& out) {
      std::vector<const double*> blocks;
      if (np_ > 0) blocks.push_back(physical.data());
      blocks.push_back(&offset);
      blocks.push_back(&contact);
      return (*functor_)(blocks.data(), out.data());
    };
    auto step = [](double x) { return x == 0.0 ? 1e-6 : 1e-6 * std::abs(x); };
    auto central = [&](double& x, double* column, std::size_t stride) {
      const double h = step(x);
      const double x0 = x;
      x = x0 + h;
      bool ok = run(plus);
      x = x0 - h;
      ok = run(minus) && ok;
      x = x0;
      for (std::size_t r = 0; r < m; ++r) column[r * stride] = (plus[r] - minus[r]) / (2.0 * h);
      return ok;
    };
    if (np_ > 0 && jacobians[0] != nullptr) {
      double* j = jacobians[0];
      std::vector<bool> in_table(np_, false);
      for (const LocalTable& t : tables_)
        for (std::size_t k = 0; k < t.size; ++k) in_table[t.first + k] = true;
      for (std::size_t c = 0; c < np_; ++c)
        if (!in_table[c] && !central(physical[c], j + c, np_)) return false;
      const std::size_t samples = m / 2;
      for (const LocalTable& t : tables_) {
        double largest = 0.0;
        for (std::size_t k = 0; k < t.size; ++k)
          largest = std::max(largest, std::abs(physical[t.first + k]));
        const double h = 1e-6 * std::max(largest, 1e-3);
        for (std::size_t k = 0; k < t.size; ++k) physical[t.first + k] += h;
        bool ok = run(plus);
        for (std::size_t k = 0; k < t.size; ++k) physical[t.first + k] -= 2.0 * h;
        ok = run(minus) && ok;
        for (std::size_t k = 0; k < t.size; ++k) physical[t.first + k] += h;
        if (!ok) return false;
        for (std::size_t r = 0; r < m; ++r) {
          double* row = j + r * np_;
          for (std::size_t k = 0; k < t.size; ++k) row[t.first + k] = 0.0;
          const double d = (plus[r] - minus[r]) / (2.0 * h);
          const std::size_t s = r % samples;
          for (int c = 0; c < t.count[s]; ++c) row[t.first + t.columns[s][c]] = d * t.weights[s][c];
        }
      }
    }
    double* jo = jacobians[np_ > 0 ? 1 : 0];
    if (jo != nullptr)
      for (std::size_t r = 0; r < m; ++r) jo[r] = r < m / 2 ? 1.0 / tip_noise_ : 0.0;
    double* jc = jacobians[np_ > 0 ? 2 : 1];
    if (jc != nullptr && !central(contact, jc, 1)) return false;
    return true;
  }

 private:
  std::unique_ptr<TrialResidual> functor_;
  std::size_t np_;
  std::vector<LocalTable> tables_;
  double tip_noise_;
};

// Where a table block's first value sits among the model's parameters; np when the model
// has no such block (or it does not fit).
std::size_t FirstParameter(const hw::TransmissionModel& model, const TabulatedBlock& t) {
  const auto& info = model.parameter_info();
  const std::size_t np = info.size();
  for (std::size_t i = 0; i < np; ++i) {
    if (info[i].qualified_name != t.first) continue;
    return i + t.size() <= np && t.size() > 0 ? i : np;
  }
  return np;
}

// The local table blocks of one trial (TabulatedBlock::local, every input a signal or the
// geometry), with each fit sample's hat functions.
std::vector<LocalTable> LocalTables(const hw::TransmissionModel& model,
                                    const std::vector<TabulatedBlock>& blocks, const LabTrial& lt) {
  std::vector<LocalTable> out;
  for (const TabulatedBlock& b : blocks) {
    if (!b.local || b.knots.size() != b.inputs.size() || b.inputs.empty()) continue;
    const std::size_t first = FirstParameter(model, b);
    if (first == model.parameter_info().size()) continue;
    std::vector<ShapeAxis> axes;
    for (std::size_t a = 0; a < b.inputs.size(); ++a) axes.push_back({b.inputs[a], b.knots[a]});
    LocalTable t;
    t.first = first;
    t.size = b.size();
    bool ok = true;
    for (std::size_t i : lt.fit_index) {
      double x[2] = {0.0, 0.0};
      for (std::size_t a = 0; a < b.inputs.size(); ++a)
        ok = SignalInput(lt, b.inputs[a], i, x[a]) && ok;
      std::array<std::size_t, 4> c{};
      std::array<double, 4> w{};
      t.count.push_back(ShapeBasis(axes, x, c.data(), w.data()));
      t.columns.push_back(c);
      t.weights.push_back(w);
    }
    if (ok) out.push_back(std::move(t));
  }
  return out;
}

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
    std::vector<double*> blocks;
    if (np > 0 && !fix_physical) blocks.push_back(physical);
    blocks.push_back(&offsets[k]);
    blocks.push_back(&contacts[k]);
    std::vector<LocalTable> local = LocalTables(prototype, options.tables, lt);
    if (!local.empty() && !fix_physical) {
      problem.AddResidualBlock(
          new TableTrialCost(functor, np, fix_physical, std::move(local), ds.noise.tip_mm), nullptr,
          blocks);
    } else {
      auto* cost = new ceres::DynamicNumericDiffCostFunction<TrialResidual, ceres::CENTRAL>(
          functor, ceres::TAKE_OWNERSHIP);
      if (np > 0 && !fix_physical) cost->AddParameterBlock(static_cast<int>(np));
      cost->AddParameterBlock(1);
      cost->AddParameterBlock(1);
      cost->SetNumResiduals(functor->num_residuals());
      problem.AddResidualBlock(cost, nullptr, blocks);
    }
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
    double fit_samples = 0.0;
    for (std::size_t k : subset) fit_samples += static_cast<double>(ds.trials[k].fit_index.size());
    for (const TabulatedBlock& pen : options.tables) {
      const std::size_t first = FirstParameter(prototype, pen);
      if (first == np || pen.lambda <= 0.0) continue;
      const std::size_t n1 = pen.knots.size() > 1 ? pen.knots[1].size() : 1;
      auto* cost = new SmoothnessResidual(np, first, pen.knots[0].size(), n1,
                                          std::sqrt(pen.lambda * fit_samples) / pen.scale);
      if (cost->empty()) {
        delete cost;
        continue;
      }
      problem.AddResidualBlock(cost, nullptr, physical);
    }
  }

  // Every trial once at the starting values, on this thread: an effect that refuses the
  // data (a tabulated term used outside its knots) throws here with its message.
  {
    Prediction scratch;
    for (std::size_t k = 0; k < subset.size(); ++k) {
      const LabTrial& lt = ds.trials[subset[k]];
      hw::TransmissionModel model(registry, effects, lt.trial.config);
      if (np > 0) model.SetParametersForFit(result.parameters.data());
      PredictTrial(model, lt, {offsets[k], contacts[k]}, scratch);
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

std::size_t TabulatedBlock::size() const {
  std::size_t n = knots.empty() ? 0 : 1;
  for (const auto& k : knots) n *= k.size();
  return n;
}

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
