#include "lab/effect_discovery.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>

#include "hw/effect_registry.h"
#include "lab/candidate_ranking.h"

namespace echoservo::lab {
namespace {

enum class Shape { kLinear, kQuadratic, kCubic, kBump };

// Trials the choice between screened terms is made on (spread over a larger dataset).

struct HookInfo {
  const char* hook;
  const char* channel;
  const char* words;  // what the hook adds to
  const char* unit;
};

constexpr HookInfo kFriction{"friction_n", "force", "friction magnitude", "N"};
constexpr HookInfo kScale{"friction_scale", "force", "friction magnitude scale", "1"};
constexpr HookInfo kForce{"force_n", "force", "force", "N"};
constexpr HookInfo kSensor{"sensor_offset_mm", "tip", "tip reading", "mm"};
constexpr HookInfo kDrive{"drive_offset_mm", "tip", "drive position", "mm"};

// A library term: coefficient × shape(input) (× scale) added to a hook.
struct Term {
  HookInfo hook;
  std::string variable;  // `where` variable it lives along
  std::string input;     // the hook's input the expression reads
  Shape shape = Shape::kLinear;
  double scale = 1.0;  // fixed factor (1e-3 turns kg·mm/s² into N)
  std::string factor;  // a second input the term is proportional to ("" for none)
  std::string coefficient_unit;
  double center = 0.0;  // bump centre and width, in the input's unit
  double width = 1.0;
  double lower = 0.0;  // the input's range in the data
  double upper = 0.0;
  double coefficient = 0.0;  // screened value
  double gain = 0.0;         // screened held-out gain, noise variances
  std::string Id() const {
    static const char* names[] = {"linear", "quadratic", "cubic", "bump"};
    return std::string(hook.hook) + ":" + names[static_cast<int>(shape)] + "(" + input + ")" +
           (factor.empty() ? "" : "*" + factor);
  }
};

const std::map<std::string, std::string>& Units() {
  static const std::map<std::string, std::string> units = {{"base_mm", "mm"},
                                                           {"tip_mm", "mm"},
                                                           {"tip_model_mm", "mm"},
                                                           {"force_model_n", "N"},
                                                           {"velocity_mm_s", "mm/s"},
                                                           {"speed_mm_s", "mm/s"},
                                                           {"acceleration_mm_s2", "mm/s^2"},
                                                           {"force_n", "N"},
                                                           {"time_s", "s"},
                                                           {"bend_deg", "deg"},
                                                           {"gap_mm", "mm"},
                                                           {"tip_load_n", "N"}};
  return units;
}

std::string PowerUnit(const std::string& unit, int power) {
  if (power == 1) return unit;
  const bool compound = unit.find('/') != std::string::npos || unit.find('^') != std::string::npos;
  return (compound ? "(" + unit + ")" : unit) + "^" + std::to_string(power);
}

std::string CoefficientUnit(const HookInfo& h, const std::string& input, Shape shape,
                            double scale) {
  if (scale != 1.0) return "kg";  // inertia: N = kg × mm/s² × 1e-3
  if (shape == Shape::kBump) return h.unit;
  const int power = shape == Shape::kLinear ? 1 : shape == Shape::kQuadratic ? 2 : 3;
  return std::string(h.unit) + "/" + PowerUnit(Units().at(input), power);
}

double ShapeValue(const Term& t, double x) {
  switch (t.shape) {
    case Shape::kLinear:
      return t.scale * x;
    case Shape::kQuadratic:
      return t.scale * x * x;
    case Shape::kCubic:
      return t.scale * x * x * x;
    case Shape::kBump: {
      const double u = (x - t.center) / t.width;
      return t.scale * std::exp(-u * u);
    }
  }
  return 0.0;
}

// The terms a channel's residual along `variable` suggests.
std::vector<Term> TermsFor(const std::string& channel, const std::string& variable) {
  std::vector<Term> out;
  if (IsPair(variable)) return out;  // learned as a shape (lab/shape_learning.h)
  auto add = [&](const HookInfo& h, const std::string& input_in, Shape s, double scale = 1.0) {
    // The hooks read the model's own tip (the delayed tip) and friction force.
    const std::string input = input_in == "tip_model_mm"    ? "tip_mm"
                              : input_in == "force_model_n" ? "force_n"
                                                            : input_in;
    Term t;
    t.hook = h;
    t.variable = variable;
    t.input = input;
    t.shape = s;
    t.scale = scale;
    t.coefficient_unit = CoefficientUnit(h, input, s, scale);
    out.push_back(t);
  };
  const bool geometry = variable == "bend_deg" || variable == "gap_mm" || variable == "tip_load_n";
  if (channel == "force") {
    if (geometry) {
      add(kFriction, variable, Shape::kLinear);  // friction that grows with the configuration
      return out;
    }
    if (variable == "tip_mm" || variable == "force_n" || variable == "tip_model_mm" ||
        variable == "force_model_n")
      return out;
    const std::string speed_input = variable == "velocity_mm_s" ? "speed_mm_s" : variable;
    for (Shape s : {Shape::kLinear, Shape::kQuadratic, Shape::kBump})
      add(kFriction, speed_input, s);
    if (variable == "time_s" || variable == "base_mm") add(kScale, variable, Shape::kLinear);
    if (variable == "acceleration_mm_s2") {
      add(kForce, variable, Shape::kLinear, 1e-3);  // inertia
    } else if (variable != "velocity_mm_s") {
      add(kForce, variable, Shape::kLinear);
      add(kForce, variable, Shape::kBump);
    }
    return out;
  }
  if (geometry) return out;  // a per-trial constant on the tip is the sensor offset
  if (variable == "force_n" || variable == "force_model_n") {
    add(kDrive, variable, Shape::kLinear);
    add(kDrive, variable, Shape::kCubic);
    return out;
  }
  for (Shape s : {Shape::kLinear, Shape::kQuadratic, Shape::kBump}) add(kSensor, variable, s);
  return out;
}

// The term's effect on the channel's residual per unit coefficient (noise σ), with the
// directions the model already has (Coulomb and viscous friction, the per-trial offset)
// projected out, as the model's refit would absorb them.
std::vector<double> Signature(const Term& t, const ResidualTable& table, const LabDataset& ds) {
  const std::vector<double>& x = table.Variable(t.variable);
  const std::size_t n = table.size();
  std::vector<double> s(n, 0.0);
  const bool force = std::string(t.hook.channel) == "force";
  const double sigma = force ? ds.noise.force_n : ds.noise.tip_mm;
  const std::vector<double>* factor =
      t.factor.empty() ? nullptr
                       : &table.Variable(t.factor == "speed_mm_s" ? "velocity_mm_s" : t.factor);
  for (std::size_t i = 0; i < n; ++i) {
    const double xi = t.input == "speed_mm_s" ? std::abs(x[i]) : x[i];
    const double f = ShapeValue(t, xi) * (factor != nullptr ? std::abs((*factor)[i]) : 1.0);
    const int dir = table.direction[i];
    if (t.hook.hook == std::string(kFriction.hook)) {
      s[i] = dir * f / sigma;
    } else if (t.hook.hook == std::string(kScale.hook)) {
      // Scales the friction the base feels, about the measured force where it slides.
      s[i] = dir != 0 ? f * table.Variable("force_n")[i] / sigma : 0.0;
    } else if (t.hook.hook == std::string(kForce.hook)) {
      s[i] = dir != 0 ? f / sigma : 0.0;
    } else {
      s[i] = f / sigma;
    }
  }
  if (force) {
    // Out of span{direction, velocity} (Coulomb, viscous), by least squares.
    const std::vector<double>& v = table.Variable("velocity_mm_s");
    double a11 = 0, a12 = 0, a22 = 0, b1 = 0, b2 = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double d = table.direction[i];
      a11 += d * d;
      a12 += d * v[i];
      a22 += v[i] * v[i];
      b1 += d * s[i];
      b2 += v[i] * s[i];
    }
    const double det = a11 * a22 - a12 * a12;
    if (std::abs(det) > 1e-12 * std::max(a11 * a22, 1e-300)) {
      const double k1 = (a22 * b1 - a12 * b2) / det;
      const double k2 = (a11 * b2 - a12 * b1) / det;
      for (std::size_t i = 0; i < n; ++i) s[i] -= k1 * table.direction[i] + k2 * v[i];
    }
  } else {
    // Out of each trial's constant (the tip-sensor offset).
    std::map<std::size_t, std::pair<double, double>> mean;
    for (std::size_t i = 0; i < n; ++i) {
      mean[table.trial[i]].first += s[i];
      mean[table.trial[i]].second += 1.0;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const auto& [sum, count] = mean[table.trial[i]];
      s[i] -= sum / count;
    }
  }
  return s;
}

// Bump centre and width from the residual's binned profile along the input.
void PlaceBump(Term& t, const ResidualTable& table) {
  const std::vector<double>& xv = table.Variable(t.variable);
  const std::vector<double>& r = std::string(t.hook.channel) == "force" ? table.force : table.tip;
  const bool friction = t.hook.hook == std::string(kFriction.hook);
  std::vector<double> x(xv.size());
  for (std::size_t i = 0; i < x.size(); ++i)
    x[i] = t.input == "speed_mm_s" ? std::abs(xv[i]) : xv[i];
  const int bins = 16;
  const std::vector<int> b = QuantileBins(x, bins);
  std::vector<double> sum(bins, 0.0), count(bins, 0.0), xsum(bins, 0.0);
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double y = friction ? r[i] * table.direction[i] : r[i];
    if (friction && table.direction[i] == 0) continue;
    sum[static_cast<std::size_t>(b[i])] += y;
    xsum[static_cast<std::size_t>(b[i])] += x[i];
    count[static_cast<std::size_t>(b[i])] += 1.0;
  }
  std::vector<double> centre, mean;
  for (int k = 0; k < bins; ++k) {
    if (count[static_cast<std::size_t>(k)] < 5) continue;
    centre.push_back(xsum[static_cast<std::size_t>(k)] / count[static_cast<std::size_t>(k)]);
    mean.push_back(sum[static_cast<std::size_t>(k)] / count[static_cast<std::size_t>(k)]);
  }
  const auto [lo, hi] = std::minmax_element(x.begin(), x.end());
  t.lower = *lo;
  t.upper = *hi;
  const double range = std::max(*hi - *lo, 1e-6);
  if (mean.size() < 3) {
    t.center = 0.5 * (*lo + *hi);
    t.width = 0.25 * range;
    return;
  }
  // The profile's extreme relative to its median level.
  std::vector<double> sorted = mean;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                   sorted.end());
  const double level = sorted[sorted.size() / 2];
  std::size_t peak = 0;
  for (std::size_t k = 1; k < mean.size(); ++k)
    if (std::abs(mean[k] - level) > std::abs(mean[peak] - level)) peak = k;
  const double half = 0.5 * std::abs(mean[peak] - level);
  std::size_t left = peak, right = peak;
  while (left > 0 && std::abs(mean[left - 1] - level) > half) --left;
  while (right + 1 < mean.size() && std::abs(mean[right + 1] - level) > half) ++right;
  const double x_left = left > 0 ? 0.5 * (centre[left] + centre[left - 1]) : centre[left];
  const double x_right =
      right + 1 < centre.size() ? 0.5 * (centre[right] + centre[right + 1]) : centre[right];
  t.center = centre[peak];
  // exp(−u²) falls to one half at u = √ln 2.
  t.width = std::clamp(0.5 * (x_right - x_left) / std::sqrt(std::log(2.0)), range / 40.0, range);
}

// Coefficient fitted on the training folds, gain on the held-out ones (noise variances).
void Screen(Term& t, const ResidualTable& table, const LabDataset& ds) {
  if (t.shape == Shape::kBump) PlaceBump(t, table);
  const std::vector<double> s = Signature(t, table, ds);
  const std::vector<double>& r = std::string(t.hook.channel) == "force" ? table.force : table.tip;
  const int folds = *std::max_element(table.fold.begin(), table.fold.end()) + 1;
  std::vector<double> rs(static_cast<std::size_t>(folds), 0.0), ss(rs.size(), 0.0);
  double rs_all = 0.0, ss_all = 0.0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    rs[static_cast<std::size_t>(table.fold[i])] += r[i] * s[i];
    ss[static_cast<std::size_t>(table.fold[i])] += s[i] * s[i];
    rs_all += r[i] * s[i];
    ss_all += s[i] * s[i];
  }
  double gain = 0.0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const auto f = static_cast<std::size_t>(table.fold[i]);
    const double denom = ss_all - ss[f];
    const double c = denom > 0.0 ? -(rs_all - rs[f]) / denom : 0.0;
    const double after = r[i] + c * s[i];
    gain += r[i] * r[i] - after * after;
  }
  t.gain = r.empty() ? 0.0 : gain / static_cast<double>(r.size());
  t.coefficient = ss_all > 0.0 ? -rs_all / ss_all : 0.0;
}

std::string Number(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// Adds term `t` as number `k` to `spec`: its parameters and its part of the hook's
// expression (terms on one hook are summed).
void AddTerm(hw::EffectFileSpec& spec, const Term& t, int k) {
  const std::string suffix = "_" + std::to_string(k);
  const std::string c = "c" + suffix;
  const double c0 = t.coefficient;
  const double bound = std::max(10.0 * std::abs(c0), 1e-9);
  spec.parameters.push_back(
      {c, t.coefficient_unit, c0, -bound, bound, "coefficient of " + t.Id() + " (discovered)"});
  std::string expr;
  const std::string x = t.input;
  switch (t.shape) {
    case Shape::kLinear:
      expr = c + "*" + x;
      break;
    case Shape::kQuadratic:  // products, not ^: muParser evaluates ^ with pow()
      expr = c + "*" + x + "*" + x;
      break;
    case Shape::kCubic:
      expr = c + "*" + x + "*" + x + "*" + x;
      break;
    case Shape::kBump: {
      const std::string x0 = "x0" + suffix;
      const std::string w = "w" + suffix;
      const double range = std::max(t.upper - t.lower, 1e-6);
      const std::string unit = Units().at(t.input);
      spec.parameters.push_back({x0, unit, t.center, t.lower - 0.25 * range, t.upper + 0.25 * range,
                                 "centre of the bump along " + x});
      spec.parameters.push_back(
          {w, unit, t.width, range / 50.0, 2.0 * range, "width of the bump along " + x});
      const std::string u = "((" + x + "-" + x0 + ")/" + w + ")";
      expr = c + "*exp(-" + u + "*" + u + ")";
      break;
    }
  }
  if (t.scale != 1.0) expr += "*" + Number(t.scale);
  if (!t.factor.empty()) expr += "*" + t.factor;
  for (auto& [hook, text] : spec.expressions) {
    if (hook == t.hook.hook) {
      text += " + " + expr;
      return;
    }
  }
  // A scale is one plus its terms.
  const bool scale = t.hook.hook == std::string(kScale.hook);
  spec.expressions.emplace_back(t.hook.hook, scale ? "1 + " + expr : expr);
}

hw::EffectFileSpec MakeSpec(const std::vector<Term>& terms) {
  hw::EffectFileSpec spec;
  spec.name = "discovered_" + terms.front().variable;
  for (std::size_t k = 0; k < terms.size(); ++k) AddTerm(spec, terms[k], static_cast<int>(k + 1));
  spec.description = "Learnt from the data by `echoservo lab diagnose` (lab/effect_discovery.h).";
  spec.signature = std::string("a residual along ") + terms.front().variable + " in the " +
                   terms.front().hook.channel + " channel";
  return spec;
}

// The fitted values become the defaults; bounds widened where a value reached one.
void Adopt(hw::EffectFileSpec& spec, const FitResult& fit) {
  for (hw::ParameterSpec& p : spec.parameters) {
    for (const ParameterEstimate& e : fit.estimates) {
      if (e.name != spec.name + "." + p.name) continue;
      p.default_value = e.value;
      if (p.name.rfind("c_", 0) == 0) {
        const double bound = std::max(10.0 * std::abs(e.value), 1e-9);
        p.lower = -bound;
        p.upper = bound;
      }
      p.lower = std::min(p.lower, e.value);
      p.upper = std::max(p.upper, e.value);
    }
  }
}

std::string Equation(const hw::EffectFileSpec& spec, const std::vector<Term>& terms) {
  std::string out;
  for (std::size_t k = 0; k < terms.size(); ++k) {
    const Term& t = terms[k];
    auto value = [&](const std::string& name) {
      for (const hw::ParameterSpec& p : spec.parameters)
        if (p.name == name + "_" + std::to_string(k + 1))
          return Number(p.default_value) + " " + p.unit;
      return std::string("?");
    };
    if (!out.empty()) out += "; ";
    const bool scale = t.hook.hook == std::string(kScale.hook);
    out += scale ? std::string("friction magnitude x= (1 + ")
                 : std::string(t.hook.words) + " (" + t.hook.unit + ") += ";
    switch (t.shape) {
      case Shape::kLinear:
        out += value("c") + " x " + t.input;
        break;
      case Shape::kQuadratic:
        out += value("c") + " x " + t.input + "^2";
        break;
      case Shape::kCubic:
        out += value("c") + " x " + t.input + "^3";
        break;
      case Shape::kBump:
        out += value("c") + " x exp(-((" + t.input + " - " + value("x0") + ") / " + value("w") +
               ")^2)";
        break;
    }
    if (!t.factor.empty()) out += " x " + t.factor;
    if (scale) out += ")";
    if (t.scale != 1.0) out += " x " + Number(t.scale) + " (inertia: mass x acceleration)";
    if (t.hook.hook == std::string(kFriction.hook)) out += ", against the motion";
  }
  return out;
}

struct Trial {
  std::vector<Term> terms;
  hw::EffectFileSpec spec;
  std::vector<std::string> effects;
  FitResult fit;
  CrossValidation cv;
  Judgement judgement;
};

// Fits the model plus `terms` (one effect) through the transmission model and
// cross-validates it against `reference` (held-out scores of what it extends).
Trial FitTerms(const std::vector<std::string>& model, const std::vector<Term>& terms,
               const LabDataset& ds, const FitResult& start_from,
               const std::vector<double>& reference, const DiagnoseOptions& o, bool keep,
               int threads) {
  Trial t;
  t.terms = terms;
  t.spec = MakeSpec(terms);
  hw::EffectRegistry registry = FitCatalog(o.fit);
  hw::RegisterEffectSpec(registry, t.spec);
  FitOptions fo = o.fit;
  fo.registry = &registry;
  fo.threads = std::max(1, threads);
  fo.progress = nullptr;
  t.effects = model;
  t.effects.push_back(t.spec.name);
  const std::vector<double> start = StartingValues(start_from, t.effects, ds, fo);
  t.fit = FitModel(t.effects, ds, fo, {}, &start);
  t.cv = CrossValidate(t.effects, ds, fo, o.folds, &t.fit.parameters, keep);
  t.judgement =
      JudgeCandidate(reference, {t.cv.tip_mse, t.cv.force_mse}, {o.min_excess, o.min_explained});
  Adopt(t.spec, t.fit);
  return t;
}

// Screens the library along the top `where` variables of the channels that keep a
// significant excess; the best `refit` terms, best first.
// Friction terms along a signal variable scaled by the configuration or the speed (a
// friction that grows with time in proportion to the tip load).
std::vector<Term> Interactions(const std::string& variable) {
  std::vector<Term> out;
  if (variable != "time_s" && variable != "base_mm" && variable != "acceleration_mm_s2") return out;
  for (const char* factor : {"tip_load_n", "bend_deg", "gap_mm", "speed_mm_s"}) {
    Term t;
    t.hook = kFriction;
    t.variable = variable;
    t.input = variable;
    t.shape = Shape::kLinear;
    t.factor = factor;
    t.coefficient_unit = CoefficientUnit(kFriction, variable, Shape::kLinear, 1.0) + "/" +
                         PowerUnit(Units().at(factor), 1);
    out.push_back(t);
  }
  return out;
}

std::vector<Term> ScreenLibrary(const ResidualTable& table, const std::vector<WhereEntry>& where,
                                double tip_excess, double force_excess, const LabDataset& ds,
                                const DiagnoseOptions& o, const std::vector<Term>& chosen) {
  std::vector<Term> terms;
  if (force_excess >= o.min_excess) {
    std::vector<std::string> variables;
    for (const Term& c : chosen) variables.push_back(c.variable);
    int taken = 0;
    for (const WhereEntry& e : where) {
      if (e.channel == "force" && taken++ < o.variables_per_channel)
        variables.push_back(e.variable);
    }
    std::sort(variables.begin(), variables.end());
    variables.erase(std::unique(variables.begin(), variables.end()), variables.end());
    for (const std::string& v : variables) {
      for (Term& t : Interactions(v)) {
        Screen(t, table, ds);
        if (t.gain > 0.0) terms.push_back(t);
      }
    }
  }
  for (const char* channel : {"tip", "force"}) {
    const double excess = std::string(channel) == "tip" ? tip_excess : force_excess;
    int taken = 0;
    for (const WhereEntry& e : where) {
      if (e.channel != channel || taken >= o.variables_per_channel) continue;
      const bool structured = e.gain >= o.min_structure;
      if (!(excess >= o.min_excess || structured) || e.gain <= 0.0) continue;
      ++taken;
      for (Term& t : TermsFor(channel, e.variable)) {
        Screen(t, table, ds);
        if (t.gain > 0.0) terms.push_back(t);
      }
    }
  }
  std::sort(terms.begin(), terms.end(),
            [](const Term& a, const Term& b) { return a.gain > b.gain; });
  if (terms.size() > static_cast<std::size_t>(o.refit))
    terms.resize(static_cast<std::size_t>(o.refit));
  return terms;
}

}  // namespace

std::optional<Proposal> DiscoverEffect(const std::vector<std::string>& model, const LabDataset& ds,
                                       const Diagnosis& d, const ResidualTable& residuals,
                                       const DiagnoseOptions& o,
                                       const std::filesystem::path& out_dir, bool refit_all) {
  std::vector<Term> chosen;
  std::optional<Trial> best;
  std::vector<double> reference = {d.base_cv.tip_mse, d.base_cv.force_mse};
  ResidualTable table = residuals;
  std::vector<WhereEntry> where = d.where;
  double tip_excess = d.tip_excess;
  double force_excess = d.force_excess;
  FitResult start_from = d.base;
  const bool subset = ds.trials.size() > kSelectionTrials;
  const LabDataset spread = subset ? SpreadTrials(ds, kSelectionTrials) : LabDataset{};
  const LabDataset& selection = subset ? spread : ds;
  for (int round = 0; round < o.max_terms; ++round) {
    const std::vector<Term> screened =
        ScreenLibrary(table, where, tip_excess, force_excess, ds, o, chosen);
    if (screened.empty()) break;
    // The screened terms are fitted through the whole model in parallel and the one with
    // the lowest held-out residual is chosen; on a large dataset the choice is made on a
    // subset of trials spread over it (kSelectionTrials), then the chosen term alone is
    // refitted and cross-validated on every trial. It is kept if it is significant there.
    std::vector<Trial> trials(screened.size());
    ForEachInParallel(screened.size(), o.threads, [&](std::size_t i) {
      if (o.fit.progress) o.fit.progress("discovery: fitting " + screened[i].Id());
      std::vector<Term> terms = chosen;
      terms.push_back(screened[i]);
      trials[i] = FitTerms(model, terms, selection, start_from, reference, o, !subset, 1);
    });
    std::size_t choice = 0;
    for (std::size_t i = 1; i < trials.size(); ++i) {
      if (trials[i].cv.tip_mse + trials[i].cv.force_mse <
          trials[choice].cv.tip_mse + trials[choice].cv.force_mse)
        choice = i;
    }
    if (subset && !refit_all) {
      // Figures on the selection only; the caller refits what it keeps (one term).
      if (!trials[choice].judgement.significant) break;
      best = trials[choice];
      chosen = best->terms;
      break;
    }
    if (subset) {
      if (o.fit.progress) o.fit.progress("discovery: refitting " + screened[choice].Id());
      trials[choice] =
          FitTerms(model, trials[choice].terms, ds, start_from, reference, o, true, o.threads);
    }
    const Trial* pick = trials[choice].judgement.significant ? &trials[choice] : nullptr;
    if (pick == nullptr) break;
    best = *pick;
    chosen = pick->terms;
    reference = {pick->cv.tip_mse, pick->cv.force_mse};
    tip_excess = pick->cv.tip_mse - 1.0;
    force_excess = pick->cv.force_mse - 1.0;
    if (tip_excess < o.min_excess && force_excess < o.min_excess) break;
    table = BuildResidualTable(ds, pick->cv.held_out, o.folds);
    where = LocateResidual(table, tip_excess, force_excess);
    start_from = pick->fit;
  }
  if (!best) return std::nullopt;

  Proposal p;
  p.effect = best->spec;
  p.effects = best->effects;
  p.fit = std::move(best->fit);
  p.cv = std::move(best->cv);
  p.cv.held_out.clear();
  p.cv_trials = subset && !refit_all ? kSelectionTrials : ds.trials.size();
  for (const Term& t : chosen) p.terms.push_back(t.Id());
  p.equation = Equation(p.effect, chosen);
  p.effect.description = "Learnt from the data by `echoservo lab diagnose`: " + p.equation + ".";
  p.rms_mm = std::sqrt(std::max(p.cv.tip_mse, 0.0)) * ds.noise.tip_mm;
  p.force_rms_n = std::sqrt(std::max(p.cv.force_mse, 0.0)) * ds.noise.force_n;
  const std::string base = hw::FormatModelSpec(model, FitCatalog(o.fit));
  if (!out_dir.empty()) {
    std::filesystem::create_directories(out_dir);
    const std::filesystem::path file = out_dir / (p.effect.name + ".json");
    hw::WriteEffectFile(file, p.effect);
    p.effect.path = file.string();
    p.file = file.string();
    p.spec = base + "+@" + p.file;
  } else {
    p.spec = base + "+" + p.effect.name;
  }
  return p;
}

}  // namespace echoservo::lab
