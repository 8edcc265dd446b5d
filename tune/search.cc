#include "tune/search.h"

#include <nlopt.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>

namespace echoservo::tune {
namespace {

live::ParameterKind SearchAxisKind(const ParameterAxis& a) {
  const live::ParameterInfo* p = live::FindParameter(a.name);
  return p != nullptr ? p->kind : live::ParameterKind::kReal;
}

void SearchCheckRange(const ParameterAxis& a, const char* search) {
  if (!std::isfinite(a.min) || !std::isfinite(a.max) || !(a.min <= a.max)) {
    throw std::invalid_argument(std::string(search) + " search: parameter '" + a.name +
                                "' has no valid range [min, max]");
  }
}

// The objective NLopt calls, with what it needs to map [0, 1] back and to survive an
// exception (NLopt is C: an exception must not cross it).
struct SearchAdaptiveState {
  const std::vector<ParameterAxis>* axes = nullptr;
  const std::function<double(const AxisValues&)>* loss = nullptr;
  AdaptiveResult* result = nullptr;
  std::vector<double> finite;
  std::exception_ptr error;
  nlopt_opt opt = nullptr;
};

AxisValues SearchFromUnit(const std::vector<ParameterAxis>& axes, const double* u) {
  AxisValues x(axes.size());
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const double t = std::clamp(u[i], 0.0, 1.0);
    x[i] = axes[i].min + t * (axes[i].max - axes[i].min);
  }
  return x;
}

double SearchAdaptiveObjective(unsigned n, const double* u, double* grad, void* data) {
  (void)n;
  (void)grad;  // derivative-free: NLopt passes nullptr
  auto* s = static_cast<SearchAdaptiveState*>(data);
  const AxisValues x = SearchFromUnit(*s->axes, u);
  double value = 0.0;
  try {
    value = (*s->loss)(x);
  } catch (...) {
    s->error = std::current_exception();
    nlopt_force_stop(s->opt);
    return std::numeric_limits<double>::max();
  }
  if (std::isfinite(value)) {
    s->finite.push_back(value);
  } else {
    value = FailedSetPenalty(s->finite);
  }
  AdaptiveResult& r = *s->result;
  r.sets.push_back(x);
  r.losses.push_back(value);
  ++r.evaluations;
  if (r.evaluations == 1 || value < r.best_loss) {
    r.best = x;
    r.best_loss = value;
  }
  return value;
}

std::string SearchStopReason(nlopt_result rc, double resolution) {
  switch (rc) {
    case NLOPT_MAXEVAL_REACHED:
      return "evaluation budget spent";
    case NLOPT_XTOL_REACHED:
      return "converged (trust region below " + std::to_string(resolution * 100.0).substr(0, 5) +
             " % of each range)";
    case NLOPT_FTOL_REACHED:
    case NLOPT_SUCCESS:
    case NLOPT_STOPVAL_REACHED:
      return "converged";
    case NLOPT_ROUNDOFF_LIMITED:
      return "stopped: round-off limited";
    case NLOPT_FORCED_STOP:
      return "stopped";
    default:
      return "NLopt error " + std::to_string(static_cast<int>(rc));
  }
}

}  // namespace

std::vector<AxisValues> GridProposals(const std::vector<ParameterAxis>& axes) {
  if (axes.empty()) return {};
  std::size_t total = 1;
  for (const ParameterAxis& a : axes) {
    if (a.values.empty()) {
      throw std::invalid_argument("grid search: parameter '" + a.name +
                                  "' has no values (give \"values\" or \"steps\")");
    }
    total *= a.values.size();
  }
  std::vector<AxisValues> sets;
  sets.reserve(total);
  std::vector<std::size_t> index(axes.size(), 0);
  for (std::size_t k = 0; k < total; ++k) {
    AxisValues x(axes.size());
    for (std::size_t i = 0; i < axes.size(); ++i) x[i] = axes[i].values[index[i]];
    sets.push_back(std::move(x));
    // Odometer: the last axis varies fastest.
    for (std::size_t i = axes.size(); i-- > 0;) {
      if (++index[i] < axes[i].values.size()) break;
      index[i] = 0;
    }
  }
  return sets;
}

std::vector<AxisValues> RandomProposals(const std::vector<ParameterAxis>& axes, int count,
                                        std::uint64_t seed) {
  if (count < 0) throw std::invalid_argument("random search: trials must be >= 0");
  if (axes.empty() || count == 0) return {};
  std::vector<live::ParameterKind> kinds;
  for (const ParameterAxis& a : axes) {
    if (a.values.empty()) SearchCheckRange(a, "random");
    kinds.push_back(SearchAxisKind(a));
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::set<AxisValues> seen;
  std::vector<AxisValues> sets;
  // A small integer space may hold fewer distinct sets than asked: stop drawing after many
  // draws in a row gave nothing new.
  const int max_misses = 1000;
  for (int misses = 0; static_cast<int>(sets.size()) < count && misses < max_misses;) {
    AxisValues x(axes.size());
    for (std::size_t i = 0; i < axes.size(); ++i) {
      const ParameterAxis& a = axes[i];
      if (!a.values.empty()) {
        const auto k = static_cast<std::size_t>(unit(rng) * static_cast<double>(a.values.size()));
        x[i] = a.values[std::min(k, a.values.size() - 1)];
        continue;
      }
      double v = a.min + unit(rng) * (a.max - a.min);
      if (kinds[i] != live::ParameterKind::kReal) {
        v = std::clamp(std::round(v), std::ceil(a.min), std::floor(a.max));
      }
      x[i] = v;
    }
    if (seen.insert(x).second) {
      sets.push_back(std::move(x));
      misses = 0;
    } else {
      ++misses;
    }
  }
  return sets;
}

double FailedSetPenalty(const std::vector<double>& finite_losses) {
  if (finite_losses.empty()) return 1e6;
  return *std::max_element(finite_losses.begin(), finite_losses.end());
}

AdaptiveResult AdaptiveSearch(const std::vector<ParameterAxis>& axes, const AdaptiveOptions& o,
                              const std::function<double(const AxisValues&)>& loss) {
  if (axes.empty()) throw std::invalid_argument("adaptive search: no parameter to search");
  if (o.max_evaluations < 1) throw std::invalid_argument("adaptive search: trials must be >= 1");
  if (!(o.initial_step > 0.0 && o.initial_step <= 0.5))
    throw std::invalid_argument("adaptive search: initial step must be in (0, 0.5]");
  if (!(o.resolution > 0.0 && o.resolution < 1.0))
    throw std::invalid_argument("adaptive search: resolution must be in (0, 1)");
  if (!o.start.empty() && o.start.size() != axes.size())
    throw std::invalid_argument("adaptive search: start has the wrong number of values");
  for (const ParameterAxis& a : axes) {
    if (!a.values.empty()) {
      throw std::invalid_argument("adaptive search: parameter '" + a.name +
                                  "' has discrete values; BOBYQA searches a continuous range: "
                                  "give {\"min\", \"max\"} without \"values\" or \"steps\"");
    }
    SearchCheckRange(a, "adaptive");
    if (SearchAxisKind(a) != live::ParameterKind::kReal) {
      throw std::invalid_argument("adaptive search: parameter '" + a.name +
                                  "' is an integer or boolean; BOBYQA searches continuous "
                                  "parameters only: search it with \"grid\" or \"random\", or "
                                  "fix it (\"fixed\")");
    }
    if (!(a.max > a.min)) {
      throw std::invalid_argument("adaptive search: parameter '" + a.name +
                                  "' has an empty range (min == max): fix it instead");
    }
  }
  const unsigned n = static_cast<unsigned>(axes.size());
  std::vector<double> u(n, 0.5), lower(n, 0.0), upper(n, 1.0), step(n, o.initial_step);
  for (unsigned i = 0; i < n && !o.start.empty(); ++i) {
    const ParameterAxis& a = axes[i];
    u[i] = std::clamp((o.start[i] - a.min) / (a.max - a.min), 0.0, 1.0);
  }
  AdaptiveResult result;
  SearchAdaptiveState state;
  state.axes = &axes;
  state.loss = &loss;
  state.result = &result;
  nlopt_opt opt = nlopt_create(NLOPT_LN_BOBYQA, n);
  if (opt == nullptr) throw std::runtime_error("adaptive search: NLopt could not start BOBYQA");
  state.opt = opt;
  nlopt_srand(o.seed);
  nlopt_set_lower_bounds(opt, lower.data());
  nlopt_set_upper_bounds(opt, upper.data());
  nlopt_set_min_objective(opt, SearchAdaptiveObjective, &state);
  nlopt_set_maxeval(opt, o.max_evaluations);
  nlopt_set_initial_step(opt, step.data());
  nlopt_set_xtol_abs1(opt, o.resolution);
  double f = 0.0;
  const nlopt_result rc = nlopt_optimize(opt, u.data(), &f);
  nlopt_destroy(opt);
  if (state.error) std::rethrow_exception(state.error);
  result.stop_reason = SearchStopReason(rc, o.resolution);
  if (rc < 0 && rc != NLOPT_ROUNDOFF_LIMITED && rc != NLOPT_FORCED_STOP && result.evaluations == 0)
    throw std::runtime_error("adaptive search: " + result.stop_reason);
  return result;
}

}  // namespace echoservo::tune
