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

#include "hw/effects/builtin_effects.h"
#include "hw/expression.h"
#include "hw/io/durable_file.h"

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

std::vector<std::string> Variables(const EffectFileSpec& spec, const HookDefinition& hook) {
  std::vector<std::string> vars;
  for (const ParameterSpec& p : spec.parameters) vars.push_back(p.name);
  vars.insert(vars.end(), hook.inputs.begin(), hook.inputs.end());
  return vars;
}

const std::vector<std::pair<std::string, double>>& Constants() {
  static const std::vector<std::pair<std::string, double>> c = {{"pi", std::numbers::pi}};
  return c;
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

bool UsesAny(const Expression& e, const std::vector<std::string>& names) {
  const std::vector<std::string> used = e.UsedVariables();
  return std::any_of(used.begin(), used.end(), [&](const std::string& u) {
    return std::find(names.begin(), names.end(), u) != names.end();
  });
}

// Evaluates the hooks of a spec. Each expression's variables are the parameters, then the
// hook's inputs in CatheterHooks() order, written straight into the parser's slots.
class ExpressionEffect final : public DescribedEffect {
 public:
  ExpressionEffect(const EffectFileSpec& spec, EffectStage stage,
                   std::array<std::optional<Expression>, kHookCount> hooks)
      : DescribedEffect(spec.name, stage, spec.description, spec.signature, spec.parameters),
        n_params_(spec.parameters.size()),
        hooks_(std::move(hooks)) {
    if (hooks_[kFrictionN]) {
      signal_friction_ = UsesAny(*hooks_[kFrictionN],
                                 {"velocity_mm_s", "acceleration_mm_s2", "base_mm", "time_s"});
    }
    if (hooks_[kFrictionScale]) {
      signal_scale_ = UsesAny(*hooks_[kFrictionScale], {"velocity_mm_s", "acceleration_mm_s2",
                                                        "base_mm", "time_s", "speed_mm_s"});
    }
    uses_signals_ = signal_friction_ || signal_scale_ || hooks_[kForceN] || hooks_[kSensorOffsetMm];
  }

 protected:
  bool DoUsesSignals() const override { return uses_signals_; }

  // friction_n inputs: speed_mm_s, velocity_mm_s, acceleration_mm_s2, base_mm, time_s, geometry.
  double DoFrictionMagnitudeN(double speed_mm_s, const EffectContext& c,
                              const double* p) const override {
    if (!hooks_[kFrictionN] || signal_friction_) return 0.0;
    const Expression& e = *hooks_[kFrictionN];
    double* x = Prepare(e, p, 5, c);
    x[0] = speed_mm_s;
    x[1] = x[2] = x[3] = x[4] = 0.0;
    return std::max(0.0, e.Evaluate());
  }
  void DoAddFrictionMagnitudesN(std::span<const double> speed_mm_s, const EffectContext& c,
                                const double* p, std::span<double> out) const override {
    if (!hooks_[kFrictionN] || signal_friction_) return;
    const Expression& e = *hooks_[kFrictionN];
    double* x = Prepare(e, p, 5, c);
    x[1] = x[2] = x[3] = x[4] = 0.0;
    for (std::size_t i = 0; i < out.size(); ++i) {
      x[0] = speed_mm_s[i];
      out[i] += std::max(0.0, e.Evaluate());
    }
  }
  double DoSignalFrictionN(double speed_mm_s, const SampleSignals& s, const EffectContext& c,
                           const double* p) const override {
    if (!signal_friction_) return 0.0;
    const Expression& e = *hooks_[kFrictionN];
    double* x = Prepare(e, p, 5, c);
    x[0] = speed_mm_s;
    x[1] = s.velocity_mm_s;
    x[2] = s.acceleration_mm_s2;
    x[3] = s.base_mm;
    x[4] = s.time_s;
    return std::max(0.0, e.Evaluate());
  }
  void DoAddSignalFrictionsN(std::span<const double> speed_mm_s, const TrialSignals& s,
                             const EffectContext& c, const double* p,
                             std::span<double> out) const override {
    if (!signal_friction_) return;
    const Expression& e = *hooks_[kFrictionN];
    double* x = Prepare(e, p, 5, c);
    for (std::size_t i = 0; i < out.size(); ++i) {
      x[0] = speed_mm_s[i];
      x[1] = s.velocity_mm_s[i];
      x[2] = s.acceleration_mm_s2[i];
      x[3] = s.base_mm[i];
      x[4] = s.time_s[i];
      out[i] += std::max(0.0, e.Evaluate());
    }
  }
  // friction_scale inputs: velocity_mm_s, acceleration_mm_s2, base_mm, time_s, speed_mm_s,
  // geometry; with any signal it scales per sample (SignalFrictionScale).
  double DoFrictionScale(const EffectContext& c, const double* p) const override {
    if (!hooks_[kFrictionScale] || signal_scale_) return 1.0;
    const Expression& e = *hooks_[kFrictionScale];
    double* x = Prepare(e, p, 5, c);
    x[0] = x[1] = x[2] = x[3] = x[4] = 0.0;
    return std::max(0.0, e.Evaluate());
  }
  double DoSignalFrictionScale(const SampleSignals& s, const EffectContext& c,
                               const double* p) const override {
    if (!signal_scale_) return 1.0;
    const Expression& e = *hooks_[kFrictionScale];
    SetSignals(Prepare(e, p, 5, c), s);
    return std::max(0.0, e.Evaluate());
  }
  // force_n inputs: velocity_mm_s, acceleration_mm_s2, base_mm, time_s, speed_mm_s, geometry.
  double DoForceN(const SampleSignals& s, const EffectContext& c, const double* p) const override {
    if (!hooks_[kForceN]) return 0.0;
    const Expression& e = *hooks_[kForceN];
    SetSignals(Prepare(e, p, 5, c), s);
    return e.Evaluate();
  }
  void DoAddForcesN(const TrialSignals& s, const EffectContext& c, const double* p,
                    std::span<double> force_n) const override {
    if (!hooks_[kForceN]) return;
    const Expression& e = *hooks_[kForceN];
    double* x = Prepare(e, p, 5, c);
    for (std::size_t i = 0; i < force_n.size(); ++i) {
      SetSignals(x, s.At(i));
      force_n[i] += e.Evaluate();
    }
  }
  // drive_offset_mm inputs: force_n, geometry.
  double DoDriveOffsetMm(double friction_force_n, const EffectContext& c,
                         const double* p) const override {
    if (!hooks_[kDriveOffsetMm]) return 0.0;
    const Expression& e = *hooks_[kDriveOffsetMm];
    Prepare(e, p, 1, c)[0] = friction_force_n;
    return e.Evaluate();
  }
  void DoAddDriveOffsetsMm(std::span<const double> friction_force_n, const EffectContext& c,
                           const double* p, std::span<double> drive_mm) const override {
    if (!hooks_[kDriveOffsetMm]) return;
    const Expression& e = *hooks_[kDriveOffsetMm];
    double* x = Prepare(e, p, 1, c);
    for (std::size_t i = 0; i < drive_mm.size(); ++i) {
      x[0] = friction_force_n[i];
      drive_mm[i] += e.Evaluate();
    }
  }
  // backlash_width_mm inputs: width_mm, friction_level_n, geometry.
  double DoBacklashWidthMm(double width_mm, double friction_level_n, const EffectContext& c,
                           const double* p) const override {
    if (!hooks_[kBacklashWidthMm]) return width_mm;
    const Expression& e = *hooks_[kBacklashWidthMm];
    double* x = Prepare(e, p, 2, c);
    x[0] = width_mm;
    x[1] = friction_level_n;
    return std::max(0.0, e.Evaluate());
  }
  // The tip-dynamics and sensor hooks of hw::Effect see only the parameters.
  double DoTraversalTimeConstantS(const double* p) const override {
    return ParametersOnly(kTraversalTauS, p, 0.0);
  }
  double DoSensorDelayS(const double* p) const override {
    return ParametersOnly(kSensorDelayS, p, 0.0);
  }
  double DoSensorScale(const double* p) const override {
    if (!hooks_[kSensorScale]) return 1.0;
    const Expression& e = *hooks_[kSensorScale];
    std::copy(p, p + n_params_, e.Inputs().begin());
    return e.Evaluate();
  }
  // sensor_offset_mm inputs: tip_mm, time_s, base_mm, velocity_mm_s, acceleration_mm_s2,
  // geometry.
  double DoSensorOffsetMm(double tip_mm, const SampleSignals& s, const EffectContext& c,
                          const double* p) const override {
    if (!hooks_[kSensorOffsetMm]) return 0.0;
    const Expression& e = *hooks_[kSensorOffsetMm];
    double* x = Prepare(e, p, 5, c);
    x[0] = tip_mm;
    x[1] = s.time_s;
    x[2] = s.base_mm;
    x[3] = s.velocity_mm_s;
    x[4] = s.acceleration_mm_s2;
    return e.Evaluate();
  }

 private:
  // Writes the parameters and the geometry (after `inputs` hook inputs) into the slots and
  // returns the first hook input's slot.
  double* Prepare(const Expression& e, const double* p, std::size_t inputs,
                  const EffectContext& c) const {
    double* x = e.Inputs().data();
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
  double ParametersOnly(int hook, const double* p, double neutral) const {
    if (!hooks_[hook]) return neutral;
    const Expression& e = *hooks_[hook];
    std::copy(p, p + n_params_, e.Inputs().begin());
    return std::max(0.0, e.Evaluate());
  }

  std::size_t n_params_;
  std::array<std::optional<Expression>, kHookCount> hooks_;
  bool signal_friction_ = false;
  bool signal_scale_ = false;
  bool uses_signals_ = false;
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
      Hook("backlash_width_mm", {"width_mm", "friction_level_n"}, {1.0, 0.5}, "mm",
           "deadzone width (>= 0) after this effect, from the width so far"),
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
  CheckKeys(doc, {"format", "name", "description", "signature", "parameters", "expressions"}, "",
            err);
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

  std::set<std::string> inputs;
  for (const HookDefinition& h : hooks) inputs.insert(h.inputs.begin(), h.inputs.end());
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
    std::vector<double> values;
    for (const ParameterSpec& p : spec.parameters) values.push_back(p.default_value);
    values.insert(values.end(), hook->typical_inputs.begin(), hook->typical_inputs.end());
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
  Json exprs = Json::object();
  for (const auto& [hook, text] : spec.expressions) exprs[hook] = text;
  doc["expressions"] = std::move(exprs);
  return doc.dump(2) + "\n";
}

void WriteEffectFile(const std::filesystem::path& path, const EffectFileSpec& spec) {
  ReplaceFileContents(path, EffectJson(spec));
}

std::unique_ptr<Effect> MakeExpressionEffect(const EffectFileSpec& spec) {
  const std::vector<HookDefinition>& hooks = CatheterHooks();
  std::array<std::optional<Expression>, kHookCount> compiled;
  int first = -1;
  for (const auto& entry : spec.expressions) {
    const std::string& name = entry.first;
    const std::string& text = entry.second;
    const auto it = std::find_if(hooks.begin(), hooks.end(),
                                 [&](const HookDefinition& h) { return h.name == name; });
    if (it == hooks.end()) {
      throw EffectFileError((spec.path.empty() ? spec.name : spec.path) + ": expressions." + name +
                            ": not a catheter hook");
    }
    const int index = static_cast<int>(it - hooks.begin());
    compiled[static_cast<std::size_t>(index)].emplace(text, Variables(spec, *it), Constants());
    if (first < 0) first = index;
  }
  if (first < 0) {
    throw EffectFileError((spec.path.empty() ? spec.name : spec.path) +
                          ": expressions: the effect has no hook");
  }
  return std::make_unique<ExpressionEffect>(spec, StageOf(first), std::move(compiled));
}

void RegisterEffectSpec(EffectRegistry& registry, const EffectFileSpec& spec) {
  auto shared = std::make_shared<const EffectFileSpec>(spec);
  registry.Register(
      spec.name, [shared] { return MakeExpressionEffect(*shared); }, spec.path);
}

}  // namespace echoservo::hw
