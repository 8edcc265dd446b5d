#include "hw/effect_file.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>

#include "formats/durable_file.h"
#include "hw/effects/builtin_effects.h"
#include "hw/expression.h"

namespace echoservo::hw {
namespace {

using Json = nlohmann::ordered_json;

// Typical values of the inputs, used to check that an expression is finite at its
// parameters' defaults: a 0.5 mm gap, a 180° bend, 0.5 N tip load, 10 mm/s, 100 mm/s².
constexpr double kTypicalBendRad = std::numbers::pi;
constexpr double kTypicalBendDeg = 180.0;
constexpr double kTypicalGapMm = 0.5;
constexpr double kTypicalTipLoadN = 0.5;

const std::vector<std::string> kGeometryInputs = {"bend_rad", "bend_deg", "gap_mm", "tip_load_n"};

HookDefinition Hook(std::string name, std::vector<std::string> inputs, std::vector<double> typical,
                    std::string unit, std::string doc, bool geometry = true) {
  if (geometry) {
    inputs.insert(inputs.end(), kGeometryInputs.begin(), kGeometryInputs.end());
    typical.insert(typical.end(),
                   {kTypicalBendRad, kTypicalBendDeg, kTypicalGapMm, kTypicalTipLoadN});
  }
  assert(inputs.size() == typical.size());
  return {std::move(name), std::move(inputs), std::move(unit), std::move(doc), std::move(typical)};
}

bool ValidName(const std::string& s) {
  if (s.empty() || s[0] < 'a' || s[0] > 'z') return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
  });
}

std::string Join(const std::vector<std::string>& v) {
  std::string out;
  for (const std::string& s : v) out += (out.empty() ? "" : ", ") + s;
  return out;
}

std::string Num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

class FileErrors {
 public:
  explicit FileErrors(std::string origin) : origin_(std::move(origin)) {}
  [[noreturn]] void Fail(const std::string& key, const std::string& why) const {
    throw EffectFileError(origin_ + ": " + (key.empty() ? "" : key + ": ") + why);
  }

 private:
  std::string origin_;
};

const Json& Require(const Json& object, const std::string& key, const std::string& where,
                    const FileErrors& err) {
  const auto it = object.find(key);
  if (it == object.end()) err.Fail(where, "missing key '" + key + "'");
  return *it;
}

void CheckKeys(const Json& object, const std::vector<std::string>& allowed,
               const std::string& where, const FileErrors& err) {
  for (const auto& [key, value] : object.items()) {
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
      err.Fail(where.empty() ? key : where + "." + key,
               "unknown key (allowed: " + Join(allowed) + ")");
    }
  }
}

std::string String(const Json& v, const std::string& key, const FileErrors& err) {
  if (!v.is_string()) err.Fail(key, "must be a string");
  return v.get<std::string>();
}

double Number(const Json& v, const std::string& key, const FileErrors& err) {
  if (!v.is_number()) err.Fail(key, "must be a number");
  const double x = v.get<double>();
  if (!std::isfinite(x)) err.Fail(key, "must be finite");
  return x;
}

const HookDefinition* FindHook(const std::vector<HookDefinition>& hooks, const std::string& name) {
  for (const HookDefinition& h : hooks) {
    if (h.name == name) return &h;
  }
  return nullptr;
}

// An expression's variables: the explicit parameters, the hook's inputs, then the tables.
std::vector<std::string> Variables(const EffectFileSpec& spec, const HookDefinition& hook) {
  std::vector<std::string> vars;
  for (const ParameterSpec& p : spec.parameters) vars.push_back(p.name);
  vars.insert(vars.end(), hook.inputs.begin(), hook.inputs.end());
  for (const EffectTableSpec& t : spec.tables) vars.push_back(t.name);
  return vars;
}

std::string Origin(const EffectFileSpec& spec) { return spec.path.empty() ? spec.name : spec.path; }

// ------------------------------------------------------------------ tabulated terms

std::string NameRule(const std::string& name) {
  return "'" + name + "' must start with a lowercase letter and hold only a-z, 0-9 and _";
}

// Checks table `i` of `spec` against the explicit parameters, the hook inputs and the
// tables before it (each pair of tables is checked when the later one is).
void CheckTable(const EffectFileSpec& spec, std::size_t i, const std::set<std::string>& inputs,
                const FileErrors& err) {
  const EffectTableSpec& t = spec.tables[i];
  const std::string at = "tables[" + std::to_string(i) + "]";
  const auto is_parameter = [&](const std::string& name) {
    return std::any_of(spec.parameters.begin(), spec.parameters.end(),
                       [&](const ParameterSpec& p) { return p.name == name; });
  };
  if (!ValidName(t.name)) err.Fail(at + ".name", NameRule(t.name));
  if (inputs.count(t.name) != 0 || t.name == "pi")
    err.Fail(at + ".name", "'" + t.name + "' shadows an input of the hooks; rename it");
  if (is_parameter(t.name))
    err.Fail(at + ".name", "'" + t.name + "' is also the name of a parameter; rename one");
  for (std::size_t j = 0; j < i; ++j) {
    if (spec.tables[j].name == t.name)
      err.Fail(at + ".name", "duplicate table name '" + t.name + "'");
  }

  if (t.inputs.empty() || t.inputs.size() > 2) {
    err.Fail(at + ".inputs",
             "must name 1 or 2 hook inputs (it names " + std::to_string(t.inputs.size()) + ")");
  }
  for (std::size_t a = 0; a < t.inputs.size(); ++a) {
    const std::string key = at + ".inputs[" + std::to_string(a) + "]";
    if (inputs.count(t.inputs[a]) == 0) {
      err.Fail(key, "unknown input '" + t.inputs[a] + "' (known: " +
                        Join(std::vector<std::string>(inputs.begin(), inputs.end())) + ")");
    }
    if (a > 0 && t.inputs[a] == t.inputs[0])
      err.Fail(key, "'" + t.inputs[a] + "' is named twice; a pair needs two different inputs");
  }

  if (t.knots.size() != t.inputs.size()) {
    err.Fail(at + ".knots", "must hold one array of knots per input (" +
                                std::to_string(t.inputs.size()) + " inputs, " +
                                std::to_string(t.knots.size()) + " arrays)");
  }
  std::size_t count = 1;
  std::string counts;
  for (std::size_t a = 0; a < t.knots.size(); ++a) {
    const std::string key = at + ".knots[" + std::to_string(a) + "]";
    const std::vector<double>& k = t.knots[a];
    if (k.size() < 2) {
      err.Fail(key, "needs at least 2 knots along " + t.inputs[a] + " (it has " +
                        std::to_string(k.size()) + ")");
    }
    for (std::size_t j = 0; j < k.size(); ++j) {
      if (!std::isfinite(k[j]))
        err.Fail(key, "knot " + Num(k[j]) + " at index " + std::to_string(j) + " is not finite");
      if (j == 0) continue;
      if (k[j] == k[j - 1]) {
        err.Fail(key, "duplicated knot " + Num(k[j]) + " at index " + std::to_string(j) +
                          " (knots must be strictly increasing)");
      }
      if (k[j] < k[j - 1]) {
        err.Fail(key, "unsorted: knot " + Num(k[j]) + " at index " + std::to_string(j) +
                          " is below " + Num(k[j - 1]) +
                          " before it (knots must be strictly increasing)");
      }
    }
    count *= k.size();
    counts += (counts.empty() ? "" : " x ") + std::to_string(k.size());
  }

  if (t.unit.empty())
    err.Fail(at + ".unit", "must not be empty (use \"1\" for a dimensionless table)");
  if (!std::isfinite(t.lower)) err.Fail(at + ".lower", "must be finite");
  if (!std::isfinite(t.upper)) err.Fail(at + ".upper", "must be finite");
  if (!(t.upper > t.lower))
    err.Fail(at + ".upper", Num(t.upper) + " must be greater than lower " + Num(t.lower));
  if (t.values.size() != count) {
    err.Fail(at + ".values", "holds " + std::to_string(t.values.size()) + " values, expected " +
                                 std::to_string(count) + " (one per knot: " + counts +
                                 ", row-major, first input slowest)");
  }
  for (std::size_t k = 0; k < t.values.size(); ++k) {
    const std::string key = at + ".values[" + std::to_string(k) + "]";
    if (!std::isfinite(t.values[k])) err.Fail(key, "must be finite");
    if (t.values[k] < t.lower || t.values[k] > t.upper) {
      err.Fail(key, Num(t.values[k]) + " is outside the bounds [" + Num(t.lower) + ", " +
                        Num(t.upper) + "]");
    }
  }

  // The knot values' parameter names must be free too.
  const auto knot_of = [](const EffectTableSpec& table, const std::string& name) {
    const std::string prefix = table.name + "_";
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) return false;
    const std::string k = name.substr(prefix.size());
    if (!std::all_of(k.begin(), k.end(), [](char c) { return c >= '0' && c <= '9'; })) return false;
    return (k == "0" || k[0] != '0') && k.size() < 10 && std::stoul(k) < table.values.size();
  };
  for (const ParameterSpec& p : spec.parameters) {
    if (knot_of(t, p.name)) {
      err.Fail(at + ".name",
               "its knot parameter '" + p.name + "' is also the name of a parameter; rename one");
    }
  }
  for (const std::string& input : inputs) {
    if (knot_of(t, input))
      err.Fail(at + ".name", "its knot parameter '" + input + "' shadows an input of the hooks");
  }
  for (std::size_t j = 0; j < i; ++j) {
    const EffectTableSpec& u = spec.tables[j];
    if (knot_of(u, t.name) || knot_of(t, u.name)) {
      err.Fail(at + ".name", "'" + t.name + "' and table '" + u.name +
                                 "' clash: a table's name is the knot parameter of the other");
    }
    for (std::size_t k = 0; k < t.values.size(); ++k) {
      if (knot_of(u, TableParameterName(t.name, k))) {
        err.Fail(at + ".name", "its knot parameter '" + TableParameterName(t.name, k) +
                                   "' is also one of table '" + u.name + "'");
      }
    }
  }
}

std::set<std::string> AllInputs(const std::vector<HookDefinition>& hooks) {
  std::set<std::string> inputs;
  for (const HookDefinition& h : hooks) inputs.insert(h.inputs.begin(), h.inputs.end());
  return inputs;
}

// The interval [k[i], k[i+1]] holding x (already inside the knots) and x's weight t in it:
// O(log K) by binary search; t is exactly 0 or 1 at a knot.
std::pair<std::size_t, double> Locate(const std::vector<double>& k, double x) {
  const std::size_t n = k.size();
  std::size_t i = static_cast<std::size_t>(std::upper_bound(k.begin(), k.end(), x) - k.begin());
  i = i == 0 ? 0 : std::min(i - 1, n - 2);
  return {i, std::clamp((x - k[i]) / (k[i + 1] - k[i]), 0.0, 1.0)};
}

// The table through `knots` with knot values `v` (row-major) at `in` (one per input, inside
// the knots): linear in one input, bilinear in a pair.
double Interpolate(const std::vector<std::vector<double>>& knots, const double* v,
                   const double* in) {
  const auto [i, ti] = Locate(knots[0], in[0]);
  if (knots.size() == 1) return (1.0 - ti) * v[i] + ti * v[i + 1];
  const auto [j, tj] = Locate(knots[1], in[1]);
  const double* r0 = v + i * knots[1].size();
  const double* r1 = r0 + knots[1].size();
  return (1.0 - ti) * ((1.0 - tj) * r0[j] + tj * r0[j + 1]) +
         ti * ((1.0 - tj) * r1[j] + tj * r1[j + 1]);
}

// A table used by one hook's expression: where its inputs and its value sit among the
// expression's variables.
struct TableUse {
  std::size_t table = 0;            // index in spec.tables
  std::size_t slot = 0;             // the table's variable
  std::array<std::size_t, 2> in{};  // its inputs' variables
};

// The tables expression `e` (variables as Variables(spec, hook)) uses. Fails, naming the
// hook, the table and the input, when the hook lacks an input of a table it uses.
std::vector<TableUse> TableUses(const Expression& e, const EffectFileSpec& spec,
                                const HookDefinition& hook, const std::string& at,
                                const FileErrors& err) {
  const std::vector<std::string> used = e.UsedVariables();
  const std::size_t n = spec.parameters.size();
  std::vector<TableUse> uses;
  for (std::size_t t = 0; t < spec.tables.size(); ++t) {
    const EffectTableSpec& table = spec.tables[t];
    if (std::find(used.begin(), used.end(), table.name) == used.end()) continue;
    TableUse u;
    u.table = t;
    u.slot = n + hook.inputs.size() + t;
    for (std::size_t a = 0; a < table.inputs.size() && a < 2; ++a) {
      const auto it = std::find(hook.inputs.begin(), hook.inputs.end(), table.inputs[a]);
      if (it == hook.inputs.end()) {
        err.Fail(at, "table " + table.name + " needs input " + table.inputs[a] + ", which hook " +
                         hook.name + " does not have (its inputs: " +
                         (hook.inputs.empty() ? "none" : Join(hook.inputs)) + ")");
      }
      u.in[a] = n + static_cast<std::size_t>(it - hook.inputs.begin());
    }
    uses.push_back(u);
  }
  return uses;
}

// The names an expression depends on: its own variables and the inputs of its tables.
std::vector<std::string> UsedNames(const Expression& e, const EffectFileSpec& spec,
                                   const std::vector<TableUse>& uses) {
  std::vector<std::string> used = e.UsedVariables();
  for (const TableUse& u : uses) {
    const auto& in = spec.tables[u.table].inputs;
    used.insert(used.end(), in.begin(), in.end());
  }
  return used;
}

// Whether the expression's text is exactly one table's name (evaluated without muParser).
bool IsJustTable(const std::string& text, const std::string& table) {
  const auto b = text.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return false;
  const auto e = text.find_last_not_of(" \t\r\n");
  return text.compare(b, e - b + 1, table) == 0 && e - b + 1 == table.size();
}

const std::vector<std::pair<std::string, double>>& Constants() {
  static const std::vector<std::pair<std::string, double>> c = {{"pi", std::numbers::pi}};
  return c;
}

std::vector<double> Numbers(const Json& v, const std::string& key, const FileErrors& err) {
  if (!v.is_array()) err.Fail(key, "must be an array of numbers");
  std::vector<double> out;
  for (std::size_t k = 0; k < v.size(); ++k)
    out.push_back(Number(v[k], key + "[" + std::to_string(k) + "]", err));
  return out;
}

// The JSON of table `at`, checked for its keys and types only (CheckTable does the rest).
EffectTableSpec ParseTable(const Json& j, const std::string& at, const FileErrors& err) {
  if (!j.is_object()) err.Fail(at, "must be an object");
  CheckKeys(j, {"name", "inputs", "knots", "values", "unit", "lower", "upper", "doc"}, at, err);
  EffectTableSpec t;
  t.name = String(Require(j, "name", at, err), at + ".name", err);
  const Json& inputs = Require(j, "inputs", at, err);
  if (!inputs.is_array()) err.Fail(at + ".inputs", "must be an array of 1 or 2 input names");
  for (std::size_t a = 0; a < inputs.size(); ++a)
    t.inputs.push_back(String(inputs[a], at + ".inputs[" + std::to_string(a) + "]", err));
  const Json& knots = Require(j, "knots", at, err);
  if (!knots.is_array()) err.Fail(at + ".knots", "must be an array of knot arrays, one per input");
  for (std::size_t a = 0; a < knots.size(); ++a)
    t.knots.push_back(Numbers(knots[a], at + ".knots[" + std::to_string(a) + "]", err));
  t.values = Numbers(Require(j, "values", at, err), at + ".values", err);
  t.unit = String(Require(j, "unit", at, err), at + ".unit", err);
  t.lower = Number(Require(j, "lower", at, err), at + ".lower", err);
  t.upper = Number(Require(j, "upper", at, err), at + ".upper", err);
  if (j.contains("doc")) t.doc = String(j["doc"], at + ".doc", err);
  return t;
}

// ------------------------------------------------------------- the expression effect

enum Hooks : int {
  kFrictionN,
  kFrictionScale,
  kForceN,
  kDriveOffsetMm,
  kBacklashWidthMm,
  kTraversalTauS,
  kSensorDelayS,
  kSensorScale,
  kSensorOffsetMm,
  kHookCount
};

EffectStage StageOf(int hook) {
  switch (hook) {
    case kDriveOffsetMm:
      return EffectStage::kCompliance;
    case kBacklashWidthMm:
      return EffectStage::kBacklash;
    case kTraversalTauS:
      return EffectStage::kTipDynamics;
    case kSensorDelayS:
    case kSensorScale:
    case kSensorOffsetMm:
      return EffectStage::kSensor;
    default:
      return EffectStage::kFriction;
  }
}

bool UsesAny(const std::vector<std::string>& used, const std::vector<std::string>& names) {
  return std::any_of(used.begin(), used.end(), [&](const std::string& u) {
    return std::find(names.begin(), names.end(), u) != names.end();
  });
}

// One compiled hook: its expression and the tables it uses.
struct CompiledHook {
  std::optional<Expression> expr;
  std::vector<TableUse> tables;
  bool just_table = false;  // the expression is exactly tables[0]'s name
  explicit operator bool() const { return expr.has_value(); }
};

// Evaluates the hooks of a spec. Each expression's variables are the parameters, then the
// hook's inputs in CatheterHooks() order, written straight into the parser's slots, then
// the tables, whose values are computed from those slots and the knot parameters.
class ExpressionEffect final : public DescribedEffect {
 public:
  ExpressionEffect(const EffectFileSpec& spec, EffectStage stage,
                   std::array<CompiledHook, kHookCount> hooks)
      : DescribedEffect(spec.name, stage, spec.description, spec.signature,
                        EffectFileParameters(spec)),
        n_params_(spec.parameters.size()),
        origin_(Origin(spec)),
        tables_(spec.tables),
        hooks_(std::move(hooks)) {
    std::size_t offset = n_params_;
    for (const EffectTableSpec& t : tables_) {
      table_offsets_.push_back(offset);
      offset += t.values.size();
    }
    const auto used = [&](int hook) {
      const CompiledHook& h = hooks_[static_cast<std::size_t>(hook)];
      return UsedNames(*h.expr, spec, h.tables);
    };
    if (hooks_[kFrictionN]) {
      signal_friction_ =
          UsesAny(used(kFrictionN), {"velocity_mm_s", "acceleration_mm_s2", "base_mm", "time_s"});
    }
    if (hooks_[kFrictionScale]) {
      signal_scale_ = UsesAny(used(kFrictionScale), {"velocity_mm_s", "acceleration_mm_s2",
                                                     "base_mm", "time_s", "speed_mm_s"});
    }
    uses_signals_ = signal_friction_ || signal_scale_ || static_cast<bool>(hooks_[kForceN]) ||
                    static_cast<bool>(hooks_[kSensorOffsetMm]);
    if (hooks_[kBacklashWidthMm]) {
      signal_backlash_ =
          UsesAny(used(kBacklashWidthMm),
                  {"velocity_mm_s", "speed_mm_s", "acceleration_mm_s2", "base_mm", "time_s"});
    }
  }

 protected:
  bool DoUsesSignals() const override { return uses_signals_; }
  bool DoUsesSignalBacklash() const override { return signal_backlash_; }

  // friction_n inputs: speed_mm_s, velocity_mm_s, acceleration_mm_s2, base_mm, time_s, geometry.
  double DoFrictionMagnitudeN(double speed_mm_s, const EffectContext& c,
                              const double* p) const override {
    const CompiledHook& h = hooks_[kFrictionN];
    if (!h || signal_friction_) return 0.0;
    double* x = Prepare(h, p, 5, c);
    x[0] = speed_mm_s;
    x[1] = x[2] = x[3] = x[4] = 0.0;
    return std::max(0.0, Eval(h, p));
  }
  void DoAddFrictionMagnitudesN(std::span<const double> speed_mm_s, const EffectContext& c,
                                const double* p, std::span<double> out) const override {
    const CompiledHook& h = hooks_[kFrictionN];
    if (!h || signal_friction_) return;
    double* x = Prepare(h, p, 5, c);
    x[1] = x[2] = x[3] = x[4] = 0.0;
    for (std::size_t i = 0; i < out.size(); ++i) {
      x[0] = speed_mm_s[i];
      out[i] += std::max(0.0, Eval(h, p));
    }
  }
  double DoSignalFrictionN(double speed_mm_s, const SampleSignals& s, const EffectContext& c,
                           const double* p) const override {
    if (!signal_friction_) return 0.0;
    const CompiledHook& h = hooks_[kFrictionN];
    double* x = Prepare(h, p, 5, c);
    x[0] = speed_mm_s;
    x[1] = s.velocity_mm_s;
    x[2] = s.acceleration_mm_s2;
    x[3] = s.base_mm;
    x[4] = s.time_s;
    return std::max(0.0, Eval(h, p));
  }
  void DoAddSignalFrictionsN(std::span<const double> speed_mm_s, const TrialSignals& s,
                             const EffectContext& c, const double* p,
                             std::span<double> out) const override {
    if (!signal_friction_) return;
    const CompiledHook& h = hooks_[kFrictionN];
    double* x = Prepare(h, p, 5, c);
    for (std::size_t i = 0; i < out.size(); ++i) {
      x[0] = speed_mm_s[i];
      x[1] = s.velocity_mm_s[i];
      x[2] = s.acceleration_mm_s2[i];
      x[3] = s.base_mm[i];
      x[4] = s.time_s[i];
      out[i] += std::max(0.0, Eval(h, p));
    }
  }
  // friction_scale inputs: velocity_mm_s, acceleration_mm_s2, base_mm, time_s, speed_mm_s,
  // geometry; with any signal it scales per sample (SignalFrictionScale).
  double DoFrictionScale(const EffectContext& c, const double* p) const override {
    const CompiledHook& h = hooks_[kFrictionScale];
    if (!h || signal_scale_) return 1.0;
    double* x = Prepare(h, p, 5, c);
    x[0] = x[1] = x[2] = x[3] = x[4] = 0.0;
    return std::max(0.0, Eval(h, p));
  }
  double DoSignalFrictionScale(const SampleSignals& s, const EffectContext& c,
                               const double* p) const override {
    if (!signal_scale_) return 1.0;
    const CompiledHook& h = hooks_[kFrictionScale];
    SetSignals(Prepare(h, p, 5, c), s);
    return std::max(0.0, Eval(h, p));
  }
  // force_n inputs: velocity_mm_s, acceleration_mm_s2, base_mm, time_s, speed_mm_s, geometry.
  double DoForceN(const SampleSignals& s, const EffectContext& c, const double* p) const override {
    const CompiledHook& h = hooks_[kForceN];
    if (!h) return 0.0;
    SetSignals(Prepare(h, p, 5, c), s);
    return Eval(h, p);
  }
  void DoAddForcesN(const TrialSignals& s, const EffectContext& c, const double* p,
                    std::span<double> force_n) const override {
    const CompiledHook& h = hooks_[kForceN];
    if (!h) return;
    double* x = Prepare(h, p, 5, c);
    for (std::size_t i = 0; i < force_n.size(); ++i) {
      SetSignals(x, s.At(i));
      force_n[i] += Eval(h, p);
    }
  }
  // drive_offset_mm inputs: force_n, geometry.
  double DoDriveOffsetMm(double friction_force_n, const EffectContext& c,
                         const double* p) const override {
    const CompiledHook& h = hooks_[kDriveOffsetMm];
    if (!h) return 0.0;
    Prepare(h, p, 1, c)[0] = friction_force_n;
    return Eval(h, p);
  }
  void DoAddDriveOffsetsMm(std::span<const double> friction_force_n, const EffectContext& c,
                           const double* p, std::span<double> drive_mm) const override {
    const CompiledHook& h = hooks_[kDriveOffsetMm];
    if (!h) return;
    double* x = Prepare(h, p, 1, c);
    for (std::size_t i = 0; i < drive_mm.size(); ++i) {
      x[0] = friction_force_n[i];
      drive_mm[i] += Eval(h, p);
    }
  }
  // backlash_width_mm inputs: width_mm, friction_level_n, velocity_mm_s, speed_mm_s,
  // acceleration_mm_s2, base_mm, time_s, geometry; with any of the signals it is the width
  // sample by sample (SignalBacklashWidthMm) and the static width passes unchanged.
  double DoBacklashWidthMm(double width_mm, double friction_level_n, const EffectContext& c,
                           const double* p) const override {
    const CompiledHook& h = hooks_[kBacklashWidthMm];
    if (!h || signal_backlash_) return width_mm;
    double* x = Prepare(h, p, 7, c);
    x[0] = width_mm;
    x[1] = friction_level_n;
    x[2] = x[3] = x[4] = x[5] = x[6] = 0.0;
    return std::max(0.0, Eval(h, p));
  }
  double DoSignalBacklashWidthMm(double width_mm, double friction_level_n, const SampleSignals& s,
                                 const EffectContext& c, const double* p) const override {
    if (!signal_backlash_) return width_mm;
    const CompiledHook& h = hooks_[kBacklashWidthMm];
    double* x = Prepare(h, p, 7, c);
    x[1] = friction_level_n;
    SetBacklashSignals(x, width_mm, s);
    return std::max(0.0, Eval(h, p));
  }
  void DoSignalBacklashWidthsMm(double friction_level_n, const TrialSignals& s,
                                const EffectContext& c, const double* p,
                                std::span<double> width_mm) const override {
    if (!signal_backlash_) return;
    const CompiledHook& h = hooks_[kBacklashWidthMm];
    double* x = Prepare(h, p, 7, c);
    x[1] = friction_level_n;
    for (std::size_t i = 0; i < width_mm.size(); ++i) {
      SetBacklashSignals(x, width_mm[i], s.At(i));
      width_mm[i] = std::max(0.0, Eval(h, p));
    }
  }
  // The tip-dynamics and sensor hooks of hw::Effect see only the parameters (so no table:
  // every table has an input).
  double DoTraversalTimeConstantS(const double* p) const override {
    return ParametersOnly(kTraversalTauS, p, 0.0);
  }
  double DoSensorDelayS(const double* p) const override {
    return ParametersOnly(kSensorDelayS, p, 0.0);
  }
  double DoSensorScale(const double* p) const override {
    const CompiledHook& h = hooks_[kSensorScale];
    if (!h) return 1.0;
    std::copy(p, p + n_params_, h.expr->Inputs().begin());
    return Eval(h, p);
  }
  // sensor_offset_mm inputs: tip_mm, time_s, base_mm, velocity_mm_s, acceleration_mm_s2,
  // geometry.
  double DoSensorOffsetMm(double tip_mm, const SampleSignals& s, const EffectContext& c,
                          const double* p) const override {
    const CompiledHook& h = hooks_[kSensorOffsetMm];
    if (!h) return 0.0;
    double* x = Prepare(h, p, 5, c);
    x[0] = tip_mm;
    x[1] = s.time_s;
    x[2] = s.base_mm;
    x[3] = s.velocity_mm_s;
    x[4] = s.acceleration_mm_s2;
    return Eval(h, p);
  }

 private:
  // Writes the parameters and the geometry (after `inputs` hook inputs) into the slots and
  // returns the first hook input's slot.
  double* Prepare(const CompiledHook& h, const double* p, std::size_t inputs,
                  const EffectContext& c) const {
    double* x = h.expr->Inputs().data();
    std::copy(p, p + n_params_, x);
    double* g = x + n_params_ + inputs;
    g[0] = c.total_bend_rad;
    g[1] = c.total_bend_rad * (180.0 / std::numbers::pi);
    g[2] = c.gap_mm;
    g[3] = c.tip_load_n;
    return x + n_params_;
  }
  static void SetSignals(double* x, const SampleSignals& s) {
    x[0] = s.velocity_mm_s;
    x[1] = s.acceleration_mm_s2;
    x[2] = s.base_mm;
    x[3] = s.time_s;
    x[4] = std::abs(s.velocity_mm_s);
  }
  static void SetBacklashSignals(double* x, double width_mm, const SampleSignals& s) {
    x[0] = width_mm;
    x[2] = s.velocity_mm_s;
    x[3] = std::abs(s.velocity_mm_s);
    x[4] = s.acceleration_mm_s2;
    x[5] = s.base_mm;
    x[6] = s.time_s;
  }
  double ParametersOnly(int hook, const double* p, double neutral) const {
    const CompiledHook& h = hooks_[static_cast<std::size_t>(hook)];
    if (!h) return neutral;
    std::copy(p, p + n_params_, h.expr->Inputs().begin());
    return std::max(0.0, Eval(h, p));
  }
  // The hook's value once its inputs are in the slots: a table alone natively, otherwise
  // the expression with its tables' values bound.
  double Eval(const CompiledHook& h, const double* p) const {
    double* x = h.expr->Inputs().data();
    if (h.just_table) return TableValue(h.tables.front(), x, p);
    for (const TableUse& u : h.tables) x[u.slot] = TableValue(u, x, p);
    return h.expr->Evaluate();
  }
  double TableValue(const TableUse& u, const double* x, const double* p) const {
    const EffectTableSpec& t = tables_[u.table];
    std::array<double, 2> in{};
    for (std::size_t a = 0; a < t.knots.size(); ++a) {
      const double v = x[u.in[a]];
      const std::vector<double>& k = t.knots[a];
      const double tol = 1e-9 * (k.back() - k.front());
      if (!(v >= k.front() - tol && v <= k.back() + tol)) RangeError(t, a, v);
      in[a] = v;
    }
    return Interpolate(t.knots, p + table_offsets_[u.table], in.data());
  }
  [[noreturn]] void RangeError(const EffectTableSpec& t, std::size_t a, double v) const {
    throw EffectTableRangeError(origin_ + ": table " + t.name + ": " + t.inputs[a] + " = " +
                                Num(v) + " is outside its knots [" + Num(t.knots[a].front()) +
                                ", " + Num(t.knots[a].back()) +
                                "] (a tabulated term does not extrapolate; learn it on data "
                                "that covers this range)");
  }

  std::size_t n_params_;
  std::string origin_;
  std::vector<EffectTableSpec> tables_;
  std::vector<std::size_t> table_offsets_;  // each table's first knot value in `p`
  std::array<CompiledHook, kHookCount> hooks_;
  bool signal_friction_ = false;
  bool signal_scale_ = false;
  bool uses_signals_ = false;
  bool signal_backlash_ = false;
};

}  // namespace

const std::vector<HookDefinition>& CatheterHooks() {
  // Order and inputs match the Hooks enum and ExpressionEffect's slots.
  static const std::vector<HookDefinition> hooks = {
      Hook("friction_n", {"speed_mm_s", "velocity_mm_s", "acceleration_mm_s2", "base_mm", "time_s"},
           {10.0, 10.0, 100.0, 1.0, 1.0}, "N",
           "friction magnitude (>= 0) added at the base speed; with any of velocity_mm_s, "
           "acceleration_mm_s2, base_mm, time_s it is signal friction (SignalFrictionN)"),
      Hook("friction_scale",
           {"velocity_mm_s", "acceleration_mm_s2", "base_mm", "time_s", "speed_mm_s"},
           {10.0, 100.0, 1.0, 1.0, 10.0}, "1",
           "multiplier (>= 0) of the summed friction magnitude; with any of the signals it "
           "scales sample by sample (SignalFrictionScale)"),
      Hook("force_n", {"velocity_mm_s", "acceleration_mm_s2", "base_mm", "time_s", "speed_mm_s"},
           {10.0, 100.0, 1.0, 1.0, 10.0}, "N",
           "signed force added to the force sensor and to the base's load (not friction)"),
      Hook("drive_offset_mm", {"force_n"}, {0.5}, "mm",
           "offset of the drive from the base given the signed friction force force_n"),
      Hook("backlash_width_mm",
           {"width_mm", "friction_level_n", "velocity_mm_s", "speed_mm_s", "acceleration_mm_s2",
            "base_mm", "time_s"},
           {1.0, 0.5, 10.0, 10.0, 100.0, 1.0, 1.0}, "mm",
           "deadzone width (>= 0) after this effect, from the width so far; with any of "
           "velocity_mm_s, speed_mm_s, acceleration_mm_s2, base_mm, time_s it is the width "
           "sample by sample (SignalBacklashWidthMm)"),
      Hook("traversal_tau_s", {}, {}, "s", "deadzone traversal time constant (>= 0)", false),
      Hook("sensor_delay_s", {}, {}, "s", "extra tip-sensor latency (>= 0)", false),
      Hook("sensor_scale", {}, {}, "1", "tip-sensor gain", false),
      Hook("sensor_offset_mm",
           {"tip_mm", "time_s", "base_mm", "velocity_mm_s", "acceleration_mm_s2"},
           {1.0, 1.0, 1.0, 10.0, 100.0}, "mm",
           "offset added to the tip reading of the delayed tip position tip_mm"),
  };
  return hooks;
}

bool operator==(const EffectFileSpec& a, const EffectFileSpec& b) {
  const auto same = [](const ParameterSpec& p, const ParameterSpec& q) {
    return p.name == q.name && p.unit == q.unit && p.default_value == q.default_value &&
           p.lower == q.lower && p.upper == q.upper && p.doc == q.doc;
  };
  return a.name == b.name && a.description == b.description && a.signature == b.signature &&
         std::equal(a.parameters.begin(), a.parameters.end(), b.parameters.begin(),
                    b.parameters.end(), same) &&
         a.expressions == b.expressions && a.path == b.path && a.tables == b.tables;
}

std::string TableParameterName(const std::string& table, std::size_t k) {
  return table + "_" + std::to_string(k);
}

std::vector<ParameterSpec> EffectFileParameters(const EffectFileSpec& spec) {
  std::vector<ParameterSpec> out = spec.parameters;
  for (const EffectTableSpec& t : spec.tables) {
    std::vector<std::size_t> index(t.knots.size(), 0);  // of the knot, per input
    for (std::size_t k = 0; k < t.values.size(); ++k) {
      std::string at;
      for (std::size_t a = 0; a < t.knots.size() && a < t.inputs.size(); ++a) {
        if (index[a] < t.knots[a].size())
          at += (at.empty() ? "" : ", ") + t.inputs[a] + " = " + Num(t.knots[a][index[a]]);
      }
      out.push_back({TableParameterName(t.name, k), t.unit, t.values[k], t.lower, t.upper,
                     "value of table " + t.name + " at " + at});
      // Row-major: the last input fastest.
      for (std::size_t a = t.knots.size(); a-- > 0;) {
        if (++index[a] < t.knots[a].size()) break;
        index[a] = 0;
      }
    }
  }
  return out;
}

EffectFileSpec ParseEffectJson(const std::string& text, const std::string& origin,
                               const std::vector<HookDefinition>& hooks) {
  const FileErrors err(origin);
  Json doc;
  try {
    doc = Json::parse(text);
  } catch (const Json::parse_error& e) {
    // nlohmann's message gives the line and column.
    err.Fail("", std::string("invalid JSON: ") + e.what());
  }
  if (!doc.is_object()) err.Fail("", "the document must be a JSON object");
  CheckKeys(doc,
            {"format", "name", "description", "signature", "parameters", "tables", "expressions"},
            "", err);
  const std::string format = String(Require(doc, "format", "", err), "format", err);
  if (format != kEffectFileFormat) {
    err.Fail("format", "'" + format + "' is not supported (expected '" +
                           std::string(kEffectFileFormat) + "')");
  }
  EffectFileSpec spec;
  spec.name = String(Require(doc, "name", "", err), "name", err);
  if (!ValidName(spec.name)) {
    err.Fail("name",
             "'" + spec.name + "' must start with a lowercase letter and hold only a-z, 0-9 and _");
  }
  if (&hooks == &CatheterHooks()) {
    static const EffectRegistry builtin = EffectRegistry::WithBuiltinEffects();
    if (spec.name == "seed" || builtin.Contains(spec.name))
      err.Fail("name", "'" + spec.name + "' is the name of a catalog effect; choose another");
  }
  if (doc.contains("description"))
    spec.description = String(doc["description"], "description", err);
  if (doc.contains("signature")) spec.signature = String(doc["signature"], "signature", err);

  const std::set<std::string> inputs = AllInputs(hooks);
  const Json& params = Require(doc, "parameters", "", err);
  if (!params.is_array()) err.Fail("parameters", "must be an array of parameter objects");
  for (std::size_t i = 0; i < params.size(); ++i) {
    const std::string at = "parameters[" + std::to_string(i) + "]";
    const Json& p = params[i];
    if (!p.is_object()) err.Fail(at, "must be an object");
    CheckKeys(p, {"name", "unit", "default", "lower", "upper", "doc"}, at, err);
    ParameterSpec ps;
    ps.name = String(Require(p, "name", at, err), at + ".name", err);
    if (!ValidName(ps.name)) {
      err.Fail(at + ".name", "'" + ps.name +
                                 "' must start with a lowercase letter and hold only a-z, 0-9 "
                                 "and _");
    }
    if (inputs.count(ps.name) != 0 || ps.name == "pi")
      err.Fail(at + ".name", "'" + ps.name + "' shadows an input of the hooks; rename it");
    for (const ParameterSpec& q : spec.parameters) {
      if (q.name == ps.name) err.Fail(at + ".name", "duplicate parameter name '" + ps.name + "'");
    }
    ps.unit = String(Require(p, "unit", at, err), at + ".unit", err);
    if (ps.unit.empty())
      err.Fail(at + ".unit", "must not be empty (use \"1\" for a dimensionless parameter)");
    ps.default_value = Number(Require(p, "default", at, err), at + ".default", err);
    ps.lower = Number(Require(p, "lower", at, err), at + ".lower", err);
    ps.upper = Number(Require(p, "upper", at, err), at + ".upper", err);
    if (!(ps.upper > ps.lower)) {
      err.Fail(at + ".upper", Num(ps.upper) + " must be greater than lower " + Num(ps.lower));
    }
    if (ps.default_value < ps.lower || ps.default_value > ps.upper) {
      err.Fail(at + ".default", Num(ps.default_value) + " is outside the bounds [" + Num(ps.lower) +
                                    ", " + Num(ps.upper) + "]");
    }
    if (p.contains("doc")) ps.doc = String(p["doc"], at + ".doc", err);
    spec.parameters.push_back(std::move(ps));
  }

  if (doc.contains("tables")) {
    const Json& tables = doc["tables"];
    if (!tables.is_array()) err.Fail("tables", "must be an array of table objects");
    for (std::size_t i = 0; i < tables.size(); ++i) {
      spec.tables.push_back(ParseTable(tables[i], "tables[" + std::to_string(i) + "]", err));
      CheckTable(spec, i, inputs, err);
    }
  }

  const Json& exprs = Require(doc, "expressions", "", err);
  if (!exprs.is_object() || exprs.empty())
    err.Fail("expressions", "must be an object with at least one hook");
  std::vector<std::string> known;
  for (const HookDefinition& h : hooks) known.push_back(h.name);
  for (const auto& [hook_name, value] : exprs.items()) {
    const std::string at = "expressions." + hook_name;
    const HookDefinition* hook = FindHook(hooks, hook_name);
    if (hook == nullptr) err.Fail(at, "unknown hook (known: " + Join(known) + ")");
    const std::string text = String(value, at, err);
    std::optional<Expression> e;
    try {
      e.emplace(text, Variables(spec, *hook), Constants());
    } catch (const ExpressionError& x) {
      err.Fail(at, "'" + text + "': " + x.what());
    }
    const std::vector<TableUse> uses = TableUses(*e, spec, *hook, at, err);
    std::vector<double> values;
    for (const ParameterSpec& p : spec.parameters) values.push_back(p.default_value);
    values.insert(values.end(), hook->typical_inputs.begin(), hook->typical_inputs.end());
    values.resize(values.size() + spec.tables.size(), 0.0);
    // The tables at their values, with the typical inputs clamped into their knots.
    for (const TableUse& u : uses) {
      const EffectTableSpec& t = spec.tables[u.table];
      std::array<double, 2> in{};
      for (std::size_t a = 0; a < t.knots.size(); ++a)
        in[a] = std::clamp(values[u.in[a]], t.knots[a].front(), t.knots[a].back());
      values[u.slot] = Interpolate(t.knots, t.values.data(), in.data());
    }
    assert(values.size() == e->variables().size());
    const double y = e->Evaluate(values.data());
    if (!std::isfinite(y)) {
      std::string where;
      for (std::size_t k = 0; k < hook->inputs.size(); ++k)
        where += (where.empty() ? "" : ", ") + hook->inputs[k] + "=" + Num(hook->typical_inputs[k]);
      err.Fail(at, "'" + text + "' is " + Num(y) + " with the parameters at their defaults" +
                       (where.empty() ? "" : " and " + where));
    }
    spec.expressions.emplace_back(hook_name, text);
  }
  return spec;
}

EffectFileSpec ReadEffectFile(const std::filesystem::path& path,
                              const std::vector<HookDefinition>& hooks) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw EffectFileError(path.string() + ": cannot read the effect file (" + std::strerror(errno) +
                          ")");
  }
  std::stringstream text;
  text << in.rdbuf();
  EffectFileSpec spec = ParseEffectJson(text.str(), path.string(), hooks);
  spec.path = path.string();
  return spec;
}

std::string EffectJson(const EffectFileSpec& spec) {
  Json doc;
  doc["format"] = kEffectFileFormat;
  doc["name"] = spec.name;
  if (!spec.description.empty()) doc["description"] = spec.description;
  if (!spec.signature.empty()) doc["signature"] = spec.signature;
  Json params = Json::array();
  for (const ParameterSpec& p : spec.parameters) {
    Json j;
    j["name"] = p.name;
    j["unit"] = p.unit;
    j["default"] = p.default_value;
    j["lower"] = p.lower;
    j["upper"] = p.upper;
    if (!p.doc.empty()) j["doc"] = p.doc;
    params.push_back(std::move(j));
  }
  doc["parameters"] = std::move(params);
  if (!spec.tables.empty()) {
    Json tables = Json::array();
    for (const EffectTableSpec& t : spec.tables) {
      Json j;
      j["name"] = t.name;
      j["inputs"] = t.inputs;
      j["knots"] = t.knots;
      j["values"] = t.values;
      j["unit"] = t.unit;
      j["lower"] = t.lower;
      j["upper"] = t.upper;
      if (!t.doc.empty()) j["doc"] = t.doc;
      tables.push_back(std::move(j));
    }
    doc["tables"] = std::move(tables);
  }
  Json exprs = Json::object();
  for (const auto& [hook, text] : spec.expressions) exprs[hook] = text;
  doc["expressions"] = std::move(exprs);
  return doc.dump(2) + "\n";
}

void WriteEffectFile(const std::filesystem::path& path, const EffectFileSpec& spec) {
  formats::ReplaceFileContents(path, EffectJson(spec));
}

std::unique_ptr<Effect> MakeExpressionEffect(const EffectFileSpec& spec) {
  const std::vector<HookDefinition>& hooks = CatheterHooks();
  const FileErrors err(Origin(spec));
  const std::set<std::string> inputs = AllInputs(hooks);
  for (std::size_t i = 0; i < spec.tables.size(); ++i) CheckTable(spec, i, inputs, err);
  std::array<CompiledHook, kHookCount> compiled;
  int first = -1;
  for (const auto& entry : spec.expressions) {
    const std::string& name = entry.first;
    const std::string& text = entry.second;
    const auto it = std::find_if(hooks.begin(), hooks.end(),
                                 [&](const HookDefinition& h) { return h.name == name; });
    if (it == hooks.end()) err.Fail("expressions." + name, "not a catheter hook");
    const int index = static_cast<int>(it - hooks.begin());
    CompiledHook& h = compiled[static_cast<std::size_t>(index)];
    h.expr.emplace(text, Variables(spec, *it), Constants());
    h.tables = TableUses(*h.expr, spec, *it, "expressions." + name, err);
    h.just_table =
        h.tables.size() == 1 && IsJustTable(text, spec.tables[h.tables.front().table].name);
    if (first < 0) first = index;
  }
  if (first < 0) err.Fail("expressions", "the effect has no hook");
  return std::make_unique<ExpressionEffect>(spec, StageOf(first), std::move(compiled));
}

void RegisterEffectSpec(EffectRegistry& registry, const EffectFileSpec& spec) {
  auto shared = std::make_shared<const EffectFileSpec>(spec);
  registry.Register(
      spec.name, [shared] { return MakeExpressionEffect(*shared); }, spec.path);
}

}  // namespace echoservo::hw
