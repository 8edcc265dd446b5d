#include "lab/motion_terms.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include "hw/effect_file.h"
#include "hw/expression.h"

namespace echoservo::lab {
namespace {

constexpr const char* kMotionHook = "position_mm";

std::vector<hw::HookDefinition> MotionHooks() {
  hw::HookDefinition h;
  h.name = kMotionHook;
  h.inputs = MotionTermInputs();
  h.unit = "mm";
  h.doc =
      "added to the heartbeat model's position: time since the trace's first sample (s), the "
      "fitted cardiac phase wrapped to [0, 2pi) (rad), the fitted heart rate (Hz)";
  h.typical_inputs = {10.0, 1.0, 1.2};
  return {h};
}

std::vector<std::string> TermVariables(const MotionTerm& term) {
  std::vector<std::string> v = MotionTermInputs();
  v.insert(v.end(), term.parameters.begin(), term.parameters.end());
  return v;
}

std::vector<std::pair<std::string, double>> TermConstants() { return {{"pi", std::numbers::pi}}; }

void AddTermParameter(MotionTerm& t, const std::string& name, const std::string& unit,
                      double bound) {
  t.parameters.push_back(name);
  t.units.push_back(unit);
  t.start.push_back(0.0);
  t.lower.push_back(-bound);
  t.upper.push_back(bound);
}

}  // namespace

std::vector<std::string> MotionTermInputs() {
  return {"time_s", "cardiac_phase_rad", "heart_rate_hz"};
}

MotionTerm ReadMotionTerm(const std::filesystem::path& path) {
  const hw::EffectFileSpec spec = hw::ReadEffectFile(path, MotionHooks());
  MotionTerm t;
  t.kind = MotionTermKind::kFile;
  t.name = spec.name;
  t.path = path.string();
  t.equation = spec.description;
  for (const hw::ParameterSpec& p : spec.parameters) {
    t.parameters.push_back(p.name);
    t.units.push_back(p.unit);
    t.start.push_back(p.default_value);
    t.lower.push_back(p.lower);
    t.upper.push_back(p.upper);
  }
  for (const auto& [hook, text] : spec.expressions) {
    if (hook == kMotionHook) t.expression = text;
  }
  if (t.expression.empty()) {
    throw std::invalid_argument(path.string() +
                                ": key 'expressions': a motion term must define the hook "
                                "'position_mm' (inputs time_s, cardiac_phase_rad, heart_rate_hz)");
  }
  return t;
}

void WriteMotionTermFile(const std::filesystem::path& path, const std::string& name,
                         const std::string& signature, const std::vector<MotionTerm>& terms) {
  hw::EffectFileSpec spec;
  spec.name = name;
  spec.signature = signature;
  spec.path = path.string();
  std::string sum;
  for (const MotionTerm& t : terms) {
    if (!spec.description.empty()) spec.description += " + ";
    spec.description += t.equation;
    sum += (sum.empty() ? "" : " + ") + std::string("(") + t.expression + ")";
    for (std::size_t i = 0; i < t.parameters.size(); ++i) {
      spec.parameters.push_back({t.parameters[i], t.units[i], t.start[i], t.lower[i], t.upper[i],
                                 "fitted with the heartbeat model"});
    }
  }
  spec.expressions = {{kMotionHook, sum}};
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  hw::WriteEffectFile(path, spec);
}

std::vector<MotionTerm> MotionTermLibrary(int harmonics) {
  std::vector<MotionTerm> out;
  MotionTerm linear;
  linear.kind = MotionTermKind::kBaselineLinear;
  linear.name = "baseline_linear";
  AddTermParameter(linear, "slope_mm_s", "mm/s", 100.0);
  linear.expression = "slope_mm_s * time_s";
  linear.equation = "baseline drifts linearly: slope_mm_s (mm/s) * time_s (s since start)";
  out.push_back(linear);
  MotionTerm quadratic;
  quadratic.kind = MotionTermKind::kBaselineQuadratic;
  quadratic.name = "baseline_quadratic";
  AddTermParameter(quadratic, "curvature_mm_s2", "mm/s^2", 10.0);
  quadratic.expression = "curvature_mm_s2 * time_s^2";
  quadratic.equation =
      "baseline bends: curvature_mm_s2 (mm/s^2) * time_s^2 (s since start, squared)";
  out.push_back(quadratic);
  for (int k = 1; k <= harmonics; ++k) {
    const std::string ks = std::to_string(k);
    MotionTerm g;
    g.kind = MotionTermKind::kAmplitudeGrowth;
    g.harmonic = k;
    g.name = "amplitude_growth" + ks;
    AddTermParameter(g, "growth" + ks + "_cos_mm_s", "mm/s", 100.0);
    AddTermParameter(g, "growth" + ks + "_sin_mm_s", "mm/s", 100.0);
    const std::string phase = k == 1 ? "cardiac_phase_rad" : ks + " * cardiac_phase_rad";
    g.expression = "(growth" + ks + "_cos_mm_s * cos(" + phase + ") + growth" + ks +
                   "_sin_mm_s * sin(" + phase + ")) * time_s";
    g.equation = "harmonic " + ks + "'s amplitude changes linearly in time: (growth" + ks +
                 "_cos_mm_s cos(" + phase + ") + growth" + ks + "_sin_mm_s sin(" + phase +
                 ")) (mm/s) * time_s (s since start)";
    out.push_back(g);
  }
  return out;
}

MotionTermEvaluator::MotionTermEvaluator(const MotionTerm& term)
    : expression_(
          std::make_unique<hw::Expression>(term.expression, TermVariables(term), TermConstants())),
      values_(3 + term.parameters.size(), 0.0) {}
MotionTermEvaluator::~MotionTermEvaluator() = default;
MotionTermEvaluator::MotionTermEvaluator(MotionTermEvaluator&&) noexcept = default;
MotionTermEvaluator& MotionTermEvaluator::operator=(MotionTermEvaluator&&) noexcept = default;

double MotionTermEvaluator::operator()(double time_s, double phase_rad, double rate_hz,
                                       const double* parameters) const {
  values_[0] = time_s;
  values_[1] = phase_rad;
  values_[2] = rate_hz;
  for (std::size_t i = 3; i < values_.size(); ++i) values_[i] = parameters[i - 3];
  return expression_->Evaluate(values_.data());
}

}  // namespace echoservo::lab
