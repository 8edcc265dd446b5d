#include "lab/shape_learning.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>

#include "hw/effect_file.h"
#include "hw/effect_registry.h"
#include "lab/candidate_ranking.h"

namespace echoservo::lab {
namespace {

// Knots along a sample-level variable: the count whose spline predicts held-out trials best
// (a ripple of a few millimetres needs more than a drift): 12 at the data's quantiles, or 24
// or 48 evenly spaced (a periodic shape is resolved alike over the whole range).
constexpr int kSampleKnotCounts[] = {12, -24, -48};  // negative: evenly spaced
constexpr int kPairSampleKnots = 6;  // the same in a pair (one count: 4-6 × 6 values to fit)
constexpr int kTrialKnots = 6;       // along a trial-level variable alone, at most
constexpr int kPairTrialKnots = 4;   // the same in a pair
constexpr std::size_t kFormulaSamples = 20000;
constexpr std::size_t kMinTrials = 4;
constexpr int kFormulasFitted = 2;
constexpr int kShapesFitted = 2;         // screened shapes fitted through the model
constexpr int kLearningIterations = 15;  // from the linearised shape's values: close already
constexpr const char* kTable = "shape";

bool TrialLevel(const std::string& v) {
  return v == "bend_deg" || v == "gap_mm" || v == "tip_load_n";
}

std::string UnitOf(const std::string& input) {
  if (input == "speed_mm_s" || input == "velocity_mm_s") return "mm/s";
  if (input == "acceleration_mm_s2") return "mm/s^2";
  if (input == "time_s") return "s";
  if (input == "bend_deg") return "deg";
  if (input == "force_n" || input == "tip_load_n") return "N";
  return "mm";
}

// One way a term can enter the model: a hook, and the hook inputs of the variables.
struct Choice {
  std::string hook;
  std::string channel;
  std::vector<std::string> variables;
  std::vector<std::string> inputs;
  bool friction = false;     // carries the sign of the motion
  bool moving_only = false;  // a force that acts while the guidewire moves
};

// The hook input a `where` variable maps to at `hook`; "" when the hook cannot see it.
std::string InputFor(const std::string& hook, const std::string& variable) {
  if (TrialLevel(variable)) return variable;
  if (hook == "friction_n") {
    if (variable == "velocity_mm_s") return "speed_mm_s";
    if (variable == "base_mm" || variable == "time_s" || variable == "acceleration_mm_s2")
      return variable;
    return "";
  }
  if (hook == "force_n") {
    if (variable == "velocity_mm_s" || variable == "base_mm" || variable == "time_s" ||
        variable == "acceleration_mm_s2")
      return variable;
    return "";
  }
  if (hook == "friction_scale") {
    if (variable == "base_mm" || variable == "time_s") return variable;
    return "";
  }
  if (hook == "sensor_offset_mm") {
    if (variable == "tip_model_mm") return "tip_mm";
    if (variable == "velocity_mm_s" || variable == "base_mm" || variable == "time_s" ||
        variable == "acceleration_mm_s2")
      return variable;
    return "";
  }
  if (hook == "drive_offset_mm") {
    if (variable == "force_n" || variable == "force_model_n") return "force_n";
    return "";
  }
  return "";
}

std::vector<Choice> ChoicesFor(const WhereEntry& e) {
  std::vector<std::string> vars;
  if (IsPair(e.variable)) {
    const auto [a, b] = SplitPair(e.variable);
    vars = {a, b};
  } else {
    vars = {e.variable};
  }
  const bool geometry_only =
      std::all_of(vars.begin(), vars.end(), [](const std::string& v) { return TrialLevel(v); });
  std::vector<std::string> hooks;
  if (e.channel == "force") {
    hooks = {"friction_n"};
    if (!geometry_only) hooks.push_back("force_n");
    // Friction that changes as a whole (every trial's in proportion to its own level).
    if (!geometry_only && vars.size() == 1) hooks.push_back("friction_scale");
  } else {
    if (geometry_only) return {};  // a per-trial constant on the tip is the sensor offset
    hooks = {"sensor_offset_mm", "drive_offset_mm"};
  }
  std::vector<Choice> out;
  for (const std::string& hook : hooks) {
    Choice c;
    c.hook = hook;
    c.channel = e.channel;
    c.variables = vars;
    c.friction = hook == "friction_n";
    c.moving_only = hook == "force_n";
    bool ok = true;
    for (const std::string& v : vars) {
      const std::string in = InputFor(hook, v);
      if (in.empty()) ok = false;
      c.inputs.push_back(in);
    }
    if (ok) out.push_back(c);
  }
  return out;
}

// The values an input takes at every residual-table sample.
std::vector<double> InputValues(const ResidualTable& t, const std::string& variable,
                                const std::string& input) {
  const std::vector<double>& x =
      t.Variable(variable == "force_n" && input == "force_n" ? "force_model_n" : variable);
  if (input != "speed_mm_s") return x;
  std::vector<double> s(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) s[i] = std::abs(x[i]);
  return s;
}

// The range an input covers over every sample of the dataset (not only the fit samples),
// with a margin: a tabulated term refuses inputs outside its knots.
std::pair<double, double> FullRange(const LabDataset& ds, const std::string& input,
                                    const std::vector<double>& table_values) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  auto take = [&](double v) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  };
  for (double v : table_values) take(v);
  for (const LabTrial& lt : ds.trials) {
    const formats::Trial& tr = lt.trial;
    for (std::size_t i = 0; i < tr.size(); ++i) {
      if (input == "base_mm") take(tr.base_mm[i]);
      if (input == "time_s") take(tr.t_s[i] - tr.t_s.front());
      if (input == "velocity_mm_s") take(lt.velocity_mm_s[i]);
      if (input == "speed_mm_s") take(std::abs(lt.velocity_mm_s[i]));
      if (input == "acceleration_mm_s2") take(lt.acceleration_mm_s2[i]);
      if (input == "tip_mm") take(tr.tip_mm[i]);
      if (input == "force_n") take(tr.force_n[i]);
    }
  }
  const double span = std::max(hi - lo, 1e-6);
  // The model's own tip and friction force can leave the measured range; the others are
  // the measured signals themselves.
  const double margin = input == "tip_mm" || input == "force_n" ? 0.5 * span : 0.02 * span;
  if (input == "speed_mm_s" || input == "time_s") return {std::max(0.0, lo - margin), hi + margin};
  return {lo - margin, hi + margin};
}

std::vector<double> Knots(const LabDataset& ds, const std::string& variable,
                          const std::string& input, const std::vector<double>& values, int count) {
  if (TrialLevel(variable)) {
    std::vector<double> k = QuantileKnots(values, count);
    if (k.size() == 1) k = {k[0] - 1.0, k[0] + 1.0};
    return k;
  }
  const auto [lo, hi] = FullRange(ds, input, values);
  if (count < 0) {
    std::vector<double> even;
    for (int i = 0; i < -count; ++i) even.push_back(lo + (hi - lo) * i / (-count - 1));
    return even;
  }
  std::vector<double> k = QuantileKnots(values, count);
  if (k.empty()) return {lo, hi};
  k.front() = std::min(k.front(), lo);
  k.back() = std::max(k.back(), hi);
  if (k.size() == 1) k.push_back(k.front() + 1.0);
  return k;
}

struct Screened {
  Choice choice;
  SmoothShape shape;  // noise σ units
};

Screened ScreenChoice(const Choice& c, const ResidualTable& t, const LabDataset& ds,
                      int sample_knots) {
  ShapeSamples s;
  const bool force = c.channel == "force";
  const std::vector<double>& r = force ? t.force : t.tip;
  std::vector<ShapeAxis> axes;
  const bool pair = c.variables.size() == 2;
  for (std::size_t a = 0; a < c.variables.size(); ++a) {
    s.inputs.push_back(InputValues(t, c.variables[a], c.inputs[a]));
    const int count = TrialLevel(c.variables[a]) ? (pair ? kPairTrialKnots : kTrialKnots)
                                                 : (pair ? kPairSampleKnots : sample_knots);
    axes.push_back({c.inputs[a], Knots(ds, c.variables[a], c.inputs[a], s.inputs.back(), count)});
  }
  s.target.resize(r.size());
  for (std::size_t i = 0; i < r.size(); ++i) s.target[i] = -r[i];
  if (c.hook == "friction_scale") {
    // A scale multiplies the friction the model already has (its force where moving).
    const std::vector<double>& f = t.Variable("force_model_n");
    s.multiplier.resize(r.size());
    for (std::size_t i = 0; i < r.size(); ++i)
      s.multiplier[i] = t.direction[i] != 0 ? t.direction[i] * std::abs(f[i]) : 0.0;
  } else if (c.friction || c.moving_only) {
    s.multiplier.resize(r.size());
    for (std::size_t i = 0; i < r.size(); ++i)
      s.multiplier[i] = c.friction ? t.direction[i] : (t.direction[i] != 0 ? 1.0 : 0.0);
  }
  if (force) {
    // Coulomb and viscous friction refit with the term.
    std::vector<double> dir(r.size());
    for (std::size_t i = 0; i < r.size(); ++i) dir[i] = t.direction[i];
    s.nuisance = {dir, t.Variable("velocity_mm_s")};
  } else {
    s.group = t.trial;  // the per-trial tip offset
  }
  s.fold = t.fold;
  Screened out{c, FitSmoothShape(axes, s)};
  return out;
}

std::string Sig4(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::string HookWords(const std::string& hook) {
  if (hook == "friction_n") return "friction magnitude (N, against the motion)";
  if (hook == "force_n") return "force (N)";
  if (hook == "sensor_offset_mm") return "tip reading (mm)";
  if (hook == "backlash_width_mm") return "backlash width (mm)";
  if (hook == "friction_scale") return "friction scale (1, every friction times 1 + the term)";
  return "drive position (mm)";
}

std::string EffectName(const std::string& prefix, const Choice& c) {
  std::string name = prefix;
  for (const std::string& v : c.variables) name += "_" + v;
  return name;
}

hw::EffectFileSpec ShapeSpec(const Choice& c, const SmoothShape& shape, double sigma) {
  hw::EffectFileSpec spec;
  spec.name = EffectName("learned", c);
  spec.description =
      "A shape learnt from the data by `echoservo lab diagnose`: " + HookWords(c.hook) +
      " += a tabulated function of the inputs.";
  spec.signature = "a " + c.channel + " residual along " + c.variables.front() +
                   (c.variables.size() > 1 ? " and " + c.variables.back() : "");
  hw::EffectTableSpec table;
  table.name = kTable;
  table.inputs = c.inputs;
  for (const ShapeAxis& a : shape.axes) table.knots.push_back(a.knots);
  const bool scale = c.hook == "friction_scale";
  table.unit = scale ? "1" : c.channel == "force" ? "N" : "mm";
  double largest = 0.0;
  for (double v : shape.values) {
    table.values.push_back(v * sigma);
    largest = std::max(largest, std::abs(v * sigma));
  }
  const double bound = std::max(10.0 * largest, scale ? 1.0 : 20.0 * sigma);
  table.lower = scale ? std::max(-1.0, -bound) : -bound;
  table.upper = bound;
  if (c.friction) {
    // A friction magnitude cannot be negative: the shape's level is carried by Coulomb.
    const double low = *std::min_element(table.values.begin(), table.values.end());
    if (low < 0.0)
      for (double& v : table.values) v -= low;
    table.lower = 0.0;
  }
  table.doc = "learnt along " + c.variables.front() +
              (c.variables.size() > 1 ? " x " + c.variables.back() : "");
  spec.tables.push_back(table);
  spec.expressions.emplace_back(c.hook, scale ? std::string("1+") + kTable : std::string(kTable));
  return spec;
}

double Sigma(const LabDataset& ds, const std::string& channel) {
  return channel == "force" ? ds.noise.force_n : ds.noise.tip_mm;
}

// Result of fitting one effect file through the model.
struct ModelTrial {
  hw::EffectFileSpec spec;
  std::vector<std::string> effects;
  FitResult fit;
  CrossValidation cv;
  Judgement judgement;
};

ModelTrial FitThrough(const std::vector<std::string>& model, hw::EffectFileSpec spec,
                      const LabDataset& ds, const FitResult& start_from,
                      const std::vector<double>& reference, const DiagnoseOptions& o,
                      const std::vector<TabulatedBlock>& tables, bool keep, int threads) {
  ModelTrial t;
  hw::EffectRegistry registry = FitCatalog(o.fit);
  hw::RegisterEffectSpec(registry, spec);
  FitOptions fo = o.fit;
  fo.registry = &registry;
  fo.threads = std::max(1, threads);
  fo.progress = nullptr;
  fo.tables = tables;
  fo.max_iterations = std::min(fo.max_iterations, kLearningIterations);
  t.effects = model;
  t.effects.push_back(spec.name);
  const std::vector<double> start = StartingValues(start_from, t.effects, ds, fo);
  t.fit = FitModel(t.effects, ds, fo, {}, &start);
  t.cv = CrossValidate(t.effects, ds, fo, o.folds, &t.fit.parameters, keep);
  t.judgement =
      JudgeCandidate(reference, {t.cv.tip_mse, t.cv.force_mse}, {o.min_excess, o.min_explained});
  // The fitted values become the file's.
  for (const ParameterEstimate& e : t.fit.estimates) {
    const std::string prefix = spec.name + ".";
    if (e.name.rfind(prefix, 0) != 0) continue;
    const std::string local = e.name.substr(prefix.size());
    for (hw::ParameterSpec& p : spec.parameters) {
      if (p.name != local) continue;
      p.default_value = e.value;
      p.lower = std::min(p.lower, e.value);
      p.upper = std::max(p.upper, e.value);
    }
    for (hw::EffectTableSpec& table : spec.tables) {
      for (std::size_t k = 0; k < table.values.size(); ++k)
        if (hw::TableParameterName(table.name, k) == local) table.values[k] = e.value;
    }
  }
  t.spec = std::move(spec);
  return t;
}

std::vector<TabulatedBlock> TablesFor(const hw::EffectFileSpec& spec, const std::string& hook,
                                      double lambda, double sigma) {
  std::vector<TabulatedBlock> out;
  for (const hw::EffectTableSpec& t : spec.tables) {
    TabulatedBlock b;
    b.first = spec.name + "." + hw::TableParameterName(t.name, 0);
    b.inputs = t.inputs;
    b.knots = t.knots;
    b.lambda = lambda;
    b.scale = sigma;
    // These hooks act on each sample's prediction alone (lab/model_fit.h).
    b.local = hook == "friction_n" || hook == "force_n" || hook == "sensor_offset_mm" ||
              hook == "friction_scale";
    out.push_back(b);
  }
  return out;
}

bool HasBacklash(const std::vector<std::string>& model, const hw::EffectRegistry& catalog) {
  for (const std::string& e : model) {
    const auto effect = catalog.Create(e);
    if (effect != nullptr && effect->stage() == hw::EffectStage::kBacklash) return true;
  }
  return false;
}

constexpr const char* kBacklashSpeed = "formula_backlash_speed";

hw::EffectFileSpec BacklashSpeedSpec() {
  hw::EffectFileSpec spec;
  spec.name = kBacklashSpeed;
  spec.description =
      "The deadzone widens with the base speed (the guidewire lifts off the bend's wall when "
      "fast): width x (1 + k x speed).";
  spec.signature = "a tip lag growing with speed, in proportion to each trial's backlash width";
  spec.parameters.push_back(
      {"k_per_mm_s", "1/(mm/s)", 0.01, -0.005, 1.0, "relative widening per mm/s of speed"});
  spec.expressions.emplace_back("backlash_width_mm", "width_mm*(1+k_per_mm_s*speed_mm_s)");
  return spec;
}

Formula BacklashFormula(const hw::EffectFileSpec& spec) {
  Formula f;
  f.form = "backlash_speed";
  f.complexity = 1;
  f.variables = {"width_mm", "speed_mm_s"};
  f.constants.push_back({"k_per_mm_s", "1/(mm/s)", spec.parameters.front().default_value,
                         "relative widening per mm/s"});
  f.expression = "width_mm*(1+k_per_mm_s*speed_mm_s)";
  f.words = "backlash width (mm) = width_mm x (1 + " + Sig4(f.constants.front().value) +
            " /(mm/s) x speed_mm_s)";
  f.held_out_mse = NAN;
  return f;
}

// Bounds for a formula's constant refitted through the model.
void Bound(hw::ParameterSpec& p, double span) {
  const double v = p.default_value;
  const std::string& n = p.name;
  auto has = [&](const char* s) { return n.find(s) != std::string::npos; };
  if (has("phase")) {
    p.lower = v - 2.0 * std::numbers::pi;
    p.upper = v + 2.0 * std::numbers::pi;
  } else if ((has("period") || has("tau") || has("width") || n == "w" || has("power") ||
              n == "p") &&
             v > 0.0) {
    p.lower = v / 4.0;
    p.upper = v * 4.0;
  } else if (has("x0") || has("t0") || has("start") || has("centre") || has("center")) {
    p.lower = v - span;
    p.upper = v + span;
  } else {
    const double b = std::max(10.0 * std::abs(v), 1e-9);
    p.lower = -b;
    p.upper = b;
  }
}

// `lowest`: the formula's smallest value over the data (a friction magnitude below zero is
// clipped by the model, so a friction formula gets a level that keeps it above zero).
hw::EffectFileSpec FormulaSpec(const Choice& c, const Formula& f, const std::vector<double>& spans,
                               double lowest) {
  hw::EffectFileSpec spec;
  spec.name = EffectName("formula", c);
  spec.description =
      "Distilled by `echoservo lab diagnose` from a learnt shape: " + HookWords(c.hook) +
      " += " + f.words + ".";
  spec.signature = "a " + c.channel + " residual along " + c.variables.front() +
                   (c.variables.size() > 1 ? " and " + c.variables.back() : "");
  std::string expression = f.expression;  // over the hook inputs (FormulaData's variables)
  for (const FormulaConstant& k : f.constants) {
    hw::ParameterSpec p{k.name, k.unit, k.value, 0.0, 0.0, k.doc};
    Bound(p, spans.empty() ? 1.0 : spans.front());
    spec.parameters.push_back(p);
  }
  // A signed force keeps the constant level; a tip reading and a drive offset have theirs
  // absorbed by the per-trial offset; a friction magnitude gets the level that keeps it
  // positive (Coulomb friction gives up as much).
  if (c.hook == "friction_n") {
    // A fixed level (not a parameter: Coulomb friction would trade with it and leave every
    // standard deviation undefined), 10 % above what keeps the formula positive.
    if (lowest < 0.0) expression = "(" + expression + ")+" + Sig4(-1.1 * lowest);
  } else if (c.hook == "friction_scale") {
    expression = "1+(" + expression + ")";
  } else if (c.hook == "force_n") {
    hw::ParameterSpec p{"level", "N", f.offset, 0.0, 0.0, "constant level"};
    const double b = std::max(10.0 * std::abs(f.offset), 1.0);
    p.lower = -b;
    p.upper = b;
    spec.parameters.push_back(p);
    expression = "(" + expression + ")+level";
  }
  spec.expressions.emplace_back(c.hook, expression);
  return spec;
}

std::string FormulaEquation(const Choice& c, const Formula& f, const hw::EffectFileSpec& spec) {
  std::string words = f.form + ": " + f.expression;
  words += " with ";
  bool first = true;
  for (const hw::ParameterSpec& p : spec.parameters) {
    words += (first ? "" : ", ") + p.name + " = " + Sig4(p.default_value) + " " + p.unit;
    first = false;
  }
  return HookWords(c.hook) + (c.hook == "backlash_width_mm" ? " = " : " += ") + words;
}

std::string ShapeEquation(const Choice& c, const hw::EffectFileSpec& spec) {
  const hw::EffectTableSpec& t = spec.tables.front();
  std::string knots;
  for (std::size_t a = 0; a < t.knots.size(); ++a)
    knots += (a ? " x " : "") + std::to_string(t.knots[a].size());
  std::string along;
  for (std::size_t a = 0; a < t.inputs.size(); ++a)
    along += (a ? ", " : "") + t.inputs[a] + " [" + Sig4(t.knots[a].front()) + ", " +
             Sig4(t.knots[a].back()) + "] " + UnitOf(t.inputs[a]);
  return HookWords(c.hook) + " += a learnt shape of " + along + " (" + knots + " knots, tabulated)";
}

double RmsOf(double mse, double noise) { return std::sqrt(std::max(mse, 0.0)) * noise; }

}  // namespace

void RefitProposal(Proposal& p, const std::vector<std::string>& model, const LabDataset& ds,
                   const DiagnoseOptions& o) {
  if (o.fit.progress) o.fit.progress("refitting " + p.effect.name + " on every trial");
  ModelTrial t = FitThrough(model, p.effect, ds, p.fit, {p.cv.tip_mse, p.cv.force_mse}, o, {},
                            false, o.threads);
  p.effect = std::move(t.spec);
  p.fit = std::move(t.fit);
  p.cv = std::move(t.cv);
  p.cv_trials = ds.trials.size();
  p.rms_mm = RmsOf(p.cv.tip_mse, ds.noise.tip_mm);
  p.force_rms_n = RmsOf(p.cv.force_mse, ds.noise.force_n);
}

void CheckLearnVariables(const std::vector<std::string>& names, const std::string& option) {
  const std::vector<std::string> singles = {"base_mm",  "velocity_mm_s", "acceleration_mm_s2",
                                            "time_s",   "tip_model_mm",  "force_model_n",
                                            "bend_deg", "gap_mm",        "tip_load_n"};
  const std::vector<std::string> slow = {"bend_deg", "gap_mm", "tip_load_n"};
  const std::vector<std::string> fast = {"base_mm", "velocity_mm_s", "acceleration_mm_s2",
                                         "time_s"};
  auto in = [](const std::vector<std::string>& v, const std::string& x) {
    return std::find(v.begin(), v.end(), x) != v.end();
  };
  for (const std::string& name : names) {
    bool ok = in(singles, name);
    if (IsPair(name)) {
      const auto [a, b] = SplitPair(name);
      ok = in(slow, a) && in(fast, b);
    }
    if (ok) continue;
    std::string list;
    for (const std::string& v : singles) list += (list.empty() ? "" : ", ") + v;
    throw std::invalid_argument(
        option + ": '" + name + "' names no variable a shape can be learnt along (" + list +
        ", or a pair SLOW*FAST of bend_deg|gap_mm|tip_load_n with "
        "base_mm|velocity_mm_s|acceleration_mm_s2|time_s; a channel's own measurement, tip_mm "
        "or force_n, is never one)");
  }
}

std::string LearnedShape::Words() const {
  std::string along;
  for (std::size_t a = 0; a < inputs.size(); ++a) along += (a ? " x " : "") + inputs[a];
  std::string knots;
  for (std::size_t a = 0; a < shape.axes.size(); ++a)
    knots += (a ? "x" : "") + std::to_string(shape.axes[a].knots.size());
  return HookWords(hook) + " += shape(" + along + "), " + knots + " knots";
}

std::optional<Proposal> LearnMissingTerm(const std::vector<std::string>& model,
                                         const LabDataset& ds, const FitResult& base,
                                         const CrossValidation& cv, const ResidualTable& table,
                                         const std::vector<WhereEntry>& where,
                                         const DiagnoseOptions& o, ShapeLearning& learning) {
  learning = ShapeLearning{};
  if (ds.trials.size() < kMinTrials) {
    learning.note = "learning a shape needs at least " + std::to_string(kMinTrials) +
                    " trials (2 per cross-validation fold, so that a shape is judged on trials "
                    "it was not fitted to); this dataset has " +
                    std::to_string(ds.trials.size());
    return std::nullopt;
  }
  const std::vector<double> reference = {cv.tip_mse, cv.force_mse};
  // 1. Screening along the top variables of each channel that keeps an excess.
  std::vector<Screened> screened;
  auto screen = [&](const Choice& c) {
    const bool sample_level_alone = c.variables.size() == 1 && !TrialLevel(c.variables.front());
    std::optional<Screened> best;
    for (int count : kSampleKnotCounts) {
      Screened s = ScreenChoice(c, table, ds, count);
      if (!best || s.shape.held_out_gain > best->shape.held_out_gain) best = std::move(s);
      if (!sample_level_alone) break;
    }
    screened.push_back(std::move(*best));
  };
  for (const char* channel : {"tip", "force"}) {
    const double excess = (std::string(channel) == "tip" ? cv.tip_mse : cv.force_mse) - 1.0;
    if (!o.learn_along.empty()) {
      // The user's variables only.
      if (excess < o.min_excess) continue;
      for (const std::string& v : o.learn_along) {
        WhereEntry e;
        e.channel = channel;
        e.variable = v;
        for (const Choice& c : ChoicesFor(e)) screen(c);
      }
      continue;
    }
    if (excess >= o.min_excess) {
      // Interactions a binned `where` cannot see on few trials (a pair's bins hold one or two
      // trials each): every trial-level variable with 3 values or more, with the velocity
      // and the channel's best sample-level variable, screened as smooth shapes, which
      // interpolate between trials.
      std::vector<std::string> fast = {"velocity_mm_s"};
      for (const WhereEntry& e : where) {
        if (e.channel == channel && !IsPair(e.variable) && !TrialLevel(e.variable) &&
            e.variable != "velocity_mm_s" && e.variable != "tip_model_mm" &&
            e.variable != "force_model_n" && !CircularFor(channel, e.variable)) {
          fast.push_back(e.variable);
          break;
        }
      }
      for (const char* slow : {"bend_deg", "gap_mm", "tip_load_n"}) {
        std::vector<double> distinct = table.Variable(slow);
        std::sort(distinct.begin(), distinct.end());
        distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
        if (distinct.size() < 3) continue;
        for (const std::string& f : fast) {
          const std::string pair = std::string(slow) + "*" + f;
          const bool listed = std::any_of(where.begin(), where.end(), [&](const WhereEntry& e) {
            return e.channel == channel && e.variable == pair;
          });
          if (listed) continue;  // screened below with the `where` entries
          WhereEntry e;
          e.channel = channel;
          e.variable = pair;
          for (const Choice& c : ChoicesFor(e)) screen(c);
        }
      }
    }
    int taken = 0;
    for (const WhereEntry& e : where) {
      if (e.channel != channel || taken >= o.variables_per_channel) continue;
      if (!(excess >= o.min_excess || e.gain >= o.min_structure) || e.gain <= 0.0) continue;
      ++taken;
      for (const Choice& c : ChoicesFor(e)) screen(c);
    }
  }
  std::erase_if(screened, [](const Screened& s) { return !(s.shape.held_out_gain > 0.0); });
  std::stable_sort(screened.begin(), screened.end(), [](const Screened& a, const Screened& b) {
    return a.shape.held_out_gain > b.shape.held_out_gain;
  });
  const bool subset = ds.trials.size() > kSelectionTrials;
  const LabDataset spread = subset ? SpreadTrials(ds, kSelectionTrials) : LabDataset{};
  const LabDataset& selection = subset ? spread : ds;
  // A form of the grammar that acts on the model's state rather than on a residual: the
  // deadzone widening with speed (a guidewire lifting off the bend's wall when fast). Its
  // tip residual depends on the trial's own width, so no shape along one variable holds it.
  std::optional<ModelTrial> backlash;
  if (cv.tip_mse - 1.0 >= o.min_excess && HasBacklash(model, FitCatalog(o.fit))) {
    if (o.fit.progress) o.fit.progress("learning: fitting the backlash width along speed");
    try {
      backlash = FitThrough(model, BacklashSpeedSpec(), selection, base, reference, o, {}, !subset,
                            o.threads);
      if (!backlash->judgement.significant) backlash.reset();
    } catch (const std::exception&) {
      backlash.reset();
    }
  }
  if (screened.empty() && !backlash) {
    learning.note = "no shape along the top variables explains the held-out residual";
    return std::nullopt;
  }
  for (const Screened& s : screened) {
    LearnedShape l;
    l.hook = s.choice.hook;
    l.channel = s.choice.channel;
    l.variables = s.choice.variables;
    l.inputs = s.choice.inputs;
    l.unit = s.choice.hook == "friction_scale" ? "1" : s.choice.channel == "force" ? "N" : "mm";
    l.shape = s.shape;
    const double sigma = Sigma(ds, l.channel);
    for (double& v : l.shape.values) v *= sigma;
    l.screened_gain = s.shape.held_out_gain;
    learning.shapes.push_back(l);
  }

  // 2. The best screened shapes through the whole model.
  const std::size_t refit =
      std::min<std::size_t>(screened.size(), std::min(kShapesFitted, std::max(1, o.refit)));
  std::vector<ModelTrial> trials(refit);
  ForEachInParallel(refit, o.threads, [&](std::size_t i) {
    const Screened& s = screened[i];
    const double sigma = Sigma(ds, s.choice.channel);
    if (o.fit.progress) o.fit.progress("learning: fitting " + learning.shapes[i].Words());
    hw::EffectFileSpec spec = ShapeSpec(s.choice, s.shape, sigma);
    trials[i] = FitThrough(model, spec, selection, base, reference, o,
                           TablesFor(spec, s.choice.hook, s.shape.lambda, sigma), !subset, 1);
  });
  std::size_t choice = 0;
  for (std::size_t i = 0; i < refit; ++i) {
    learning.shapes[i].fitted = true;
    learning.shapes[i].tip_mse = trials[i].cv.tip_mse;
    learning.shapes[i].force_mse = trials[i].cv.force_mse;
    if (trials[i].cv.tip_mse + trials[i].cv.force_mse <
        trials[choice].cv.tip_mse + trials[choice].cv.force_mse)
      choice = i;
  }
  std::optional<ModelTrial> best_shape;
  Choice chosen;
  if (refit > 0) {
    chosen = screened[choice].choice;
    LearnedShape& l = learning.shapes[choice];
    l.shape.values = trials[choice].spec.tables.front().values;
    std::rotate(learning.shapes.begin(), learning.shapes.begin() + static_cast<long>(choice),
                learning.shapes.begin() + static_cast<long>(choice) + 1);
    if (trials[choice].judgement.significant) {
      best_shape = std::move(trials[choice]);
    } else {
      learning.note = "the best learnt shape (" + learning.shapes.front().Words() +
                      ") is not significant on held-out trials";
    }
  }
  if (!best_shape && !backlash) return std::nullopt;

  // 3. Distillation of the shape into a formula along the data's own inputs.
  struct Fitted {
    std::size_t index;  // in learning.formulas
    ModelTrial trial;
    std::string channel;  // where it is compared with the shape
  };
  std::vector<Fitted> fitted;
  if (best_shape) {
    FormulaData fd;
    const LearnedShape& ls = learning.shapes.front();
    std::vector<std::vector<double>> values;
    std::vector<double> spans;
    for (std::size_t a = 0; a < chosen.variables.size(); ++a) {
      values.push_back(InputValues(table, chosen.variables[a], chosen.inputs[a]));
      fd.variables.push_back({chosen.inputs[a], UnitOf(chosen.inputs[a])});
      const auto [lo, hi] = std::minmax_element(values.back().begin(), values.back().end());
      spans.push_back(*hi - *lo);
    }
    fd.inputs.resize(values.size());
    const std::size_t n = table.size();
    const std::size_t step = std::max<std::size_t>(1, n / kFormulaSamples);
    for (std::size_t i = 0; i < n; i += step) {
      if ((chosen.friction || chosen.moving_only) && table.direction[i] == 0) continue;
      double in[2] = {values[0][i], values.size() > 1 ? values[1][i] : 0.0};
      for (std::size_t a = 0; a < values.size(); ++a) fd.inputs[a].push_back(in[a]);
      fd.target.push_back(ls.shape.Evaluate(in));
      fd.fold.push_back(table.fold[i]);
    }
    fd.target_unit = ls.unit;
    fd.offset = true;
    std::vector<Formula> front;
    try {
      front = ParetoFront(SearchFormulas(fd));
    } catch (const std::invalid_argument& e) {
      learning.note = std::string("no formula search: ") + e.what();
    }
    std::erase_if(front, [](const Formula& f) { return f.complexity < 1; });
    for (const Formula& f : front) learning.formulas.push_back({f, false, NAN, NAN, ""});
    // The best few by their fit to the shape, each through the model.
    std::vector<std::size_t> order(learning.formulas.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return learning.formulas[a].formula.held_out_mse < learning.formulas[b].formula.held_out_mse;
    });
    if (order.size() > static_cast<std::size_t>(kFormulasFitted)) order.resize(kFormulasFitted);
    std::vector<std::optional<ModelTrial>> formula_trials(order.size());
    ForEachInParallel(order.size(), o.threads, [&](std::size_t k) {
      const Formula& f = learning.formulas[order[k]].formula;
      if (o.fit.progress) o.fit.progress("learning: fitting formula " + f.words);
      try {
        double lowest = std::numeric_limits<double>::infinity();
        for (std::size_t i = 0; i < fd.target.size(); ++i) {
          const double in[2] = {fd.inputs[0][i], fd.inputs.size() > 1 ? fd.inputs[1][i] : 0.0};
          lowest = std::min(lowest, f.Evaluate(in));
        }
        formula_trials[k] = FitThrough(model, FormulaSpec(chosen, f, spans, lowest), selection,
                                       base, reference, o, {}, !subset, 1);
      } catch (const std::exception&) {
        formula_trials[k].reset();  // a formula the model cannot run is not proposed
      }
    });
    for (std::size_t k = 0; k < order.size(); ++k)
      if (formula_trials[k])
        fitted.push_back({order[k], std::move(*formula_trials[k]), chosen.channel});
  }
  if (backlash) {
    learning.formulas.push_back({BacklashFormula(backlash->spec), false, NAN, NAN, ""});
    fitted.push_back({learning.formulas.size() - 1, std::move(*backlash), "tip"});
  }
  auto channel_mse = [](const ModelTrial& t, const std::string& channel) {
    return channel == "tip" ? t.cv.tip_mse : t.cv.force_mse;
  };
  // The simplest formula within `formula_tolerance` of the shape's held-out RMS in the channel
  // it acts on (the better of two equally simple ones); without a shape, the best formula.
  const Fitted* formula = nullptr;
  for (Fitted& f : fitted) {
    FormulaCandidate& fc = learning.formulas[f.index];
    fc.fitted = true;
    fc.tip_mse = f.trial.cv.tip_mse;
    fc.force_mse = f.trial.cv.force_mse;
    fc.equation = FormulaEquation(f.channel == "tip" && fc.formula.form == "backlash_speed"
                                      ? Choice{"backlash_width_mm", "tip", {}, {}, false, false}
                                      : chosen,
                                  fc.formula, f.trial.spec);
    if (!f.trial.judgement.significant) continue;
    const bool close =
        !best_shape ||
        std::sqrt(std::max(channel_mse(f.trial, f.channel), 0.0)) <=
            o.formula_tolerance * std::sqrt(std::max(channel_mse(*best_shape, f.channel), 0.0));
    if (!close) continue;
    const int complexity = fc.formula.complexity;
    if (formula == nullptr || complexity < learning.formulas[formula->index].formula.complexity ||
        (complexity == learning.formulas[formula->index].formula.complexity &&
         f.trial.cv.tip_mse + f.trial.cv.force_mse <
             formula->trial.cv.tip_mse + formula->trial.cv.force_mse))
      formula = &f;
  }
  if (formula == nullptr && !best_shape) return std::nullopt;

  // On a dataset larger than the selection, only what is proposed is refitted and
  // cross-validated on every trial (the others' figures are the selection's).
  const double lambda = refit > 0 ? screened[choice].shape.lambda : 0.0;
  const ModelTrial& chosen_trial = formula != nullptr ? formula->trial : *best_shape;
  ModelTrial full;
  if (subset) {
    if (o.fit.progress)
      o.fit.progress("learning: refitting " + chosen_trial.spec.name + " on every trial");
    full = FitThrough(model, chosen_trial.spec, ds, base, reference, o,
                      formula != nullptr ? std::vector<TabulatedBlock>{}
                                         : TablesFor(chosen_trial.spec, chosen.hook, lambda,
                                                     Sigma(ds, chosen.channel)),
                      true, o.threads);
    if (formula != nullptr) {
      FormulaCandidate& fc = learning.formulas[formula->index];
      fc.tip_mse = full.cv.tip_mse;
      fc.force_mse = full.cv.force_mse;
      fc.equation = fc.formula.form == "backlash_speed"
                        ? FormulaEquation({"backlash_width_mm", "tip", {}, {}, false, false},
                                          fc.formula, full.spec)
                        : FormulaEquation(chosen, fc.formula, full.spec);
    } else {
      learning.shapes.front().tip_mse = full.cv.tip_mse;
      learning.shapes.front().force_mse = full.cv.force_mse;
      learning.shapes.front().shape.values = full.spec.tables.front().values;
    }
    if (!full.judgement.significant) {
      learning.note = "what was learnt on " + std::to_string(kSelectionTrials) +
                      " trials is not significant on all " + std::to_string(ds.trials.size());
      return std::nullopt;
    }
  }

  Proposal p;
  const ModelTrial& pick = subset ? full : chosen_trial;
  p.effect = pick.spec;
  p.effects = pick.effects;
  p.fit = pick.fit;
  p.cv = pick.cv;
  p.cv.held_out.clear();
  if (formula != nullptr) {
    const FormulaCandidate& fc = learning.formulas[formula->index];
    learning.proposed = "formula";
    p.equation = fc.equation;
    const std::vector<std::string>& along =
        fc.formula.form == "backlash_speed" ? fc.formula.variables : chosen.inputs;
    p.terms.push_back("formula:" + fc.formula.form + "(" + along.front() +
                      (along.size() > 1 ? "," + along.back() : "") + ")");
    const double sigma = Sigma(ds, formula->channel);
    learning.note = best_shape
                        ? "the formula's held-out " + formula->channel + " RMS is within " +
                              Sig4(o.formula_tolerance) + "x of the learnt shape's (" +
                              Sig4(RmsOf(channel_mse(formula->trial, formula->channel), sigma)) +
                              " against " +
                              Sig4(RmsOf(channel_mse(*best_shape, formula->channel), sigma)) +
                              (formula->channel == "tip" ? " mm)" : " N)")
                        : "no learnt shape is significant; a form of the grammar that acts on the "
                          "model's state is";
  } else {
    learning.proposed = "shape";
    p.equation = ShapeEquation(chosen, pick.spec);
    p.terms.push_back("shape:" + chosen.hook + "(" + chosen.inputs.front() +
                      (chosen.inputs.size() > 1 ? "," + chosen.inputs.back() : "") + ")");
    learning.note = learning.formulas.empty()
                        ? "no formula of the grammar fits the learnt shape: the shape itself is "
                          "proposed"
                        : "no formula comes within " + Sig4(o.formula_tolerance) +
                              "x of the learnt shape's held-out error: the shape itself is "
                              "proposed";
  }
  p.effect.description = "Learnt from the data by `echoservo lab diagnose`: " + p.equation + ".";
  p.cv_trials = ds.trials.size();
  p.rms_mm = RmsOf(p.cv.tip_mse, ds.noise.tip_mm);
  p.force_rms_n = RmsOf(p.cv.force_mse, ds.noise.force_n);
  // The caller writes the file and names it in the SPEC (lab/diagnosis.cc).
  p.spec = hw::FormatModelSpec(model, FitCatalog(o.fit)) + "+" + p.effect.name;
  return p;
}

}  // namespace echoservo::lab
