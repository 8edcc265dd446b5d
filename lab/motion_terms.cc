#include "lab/motion_terms.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include "hw/effect_file.h"
#include "hw/expression.h"

namespace echoservo::lab {
namespace {

constexpr const char* kMotionHook = "position_mm";
constexpr const char* kPhaseHook = "phase_rad";

std::vector<hw::HookDefinition> MotionHooks() {
  hw::HookDefinition h;
  h.name = kMotionHook;
  h.inputs = MotionTermInputs();
  h.unit = "mm";
  h.doc =
      "added to the heartbeat model's position: time since the trace's first sample (s), the "
      "fitted cardiac phase wrapped to [0, 2pi) (rad), the fitted heart rate (Hz), the "
      "heartbeat's harmonic sum at that phase (mm)";
  h.typical_inputs = {10.0, 1.0, 1.2, 2.0};
  hw::HookDefinition phase;
  phase.name = kPhaseHook;
  phase.inputs = MotionPhaseInputs();
  phase.unit = "rad";
  phase.doc =
      "added to the heartbeat's phase before its harmonics are evaluated: time since the "
      "trace's first sample (s)";
  phase.typical_inputs = {10.0};
  return {h, phase};
}

std::vector<std::string> TermVariables(std::vector<std::string> inputs, const MotionTerm& term) {
  inputs.insert(inputs.end(), term.parameters.begin(), term.parameters.end());
  return inputs;
}

// A number for an expression: enough digits to round-trip a knot time.
std::string MotionTermNumber(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.10g", x);
  return buffer;
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

void AddBoundedParameter(MotionTerm& t, const std::string& name, const std::string& unit,
                         double start, double lower, double upper) {
  t.parameters.push_back(name);
  t.units.push_back(unit);
  t.start.push_back(std::max(lower, std::min(start, upper)));  // lower > upper: dropped later
  t.lower.push_back(lower);
  t.upper.push_back(upper);
}

}  // namespace

std::vector<std::string> MotionTermInputs() {
  return {"time_s", "cardiac_phase_rad", "heart_rate_hz", "heartbeat_mm"};
}

std::vector<std::string> MotionPhaseInputs() { return {"time_s"}; }

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
    if (hook == kPhaseHook) t.phase_expression = text;
  }
  if (t.expression.empty() && t.phase_expression.empty()) {
    throw std::invalid_argument(path.string() +
                                ": key 'expressions': a motion term must define the hook "
                                "'position_mm' (inputs time_s, cardiac_phase_rad, heart_rate_hz, "
                                "heartbeat_mm) or 'phase_rad' (input time_s)");
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
  std::string phase;
  for (const MotionTerm& t : terms) {
    if (!spec.description.empty()) spec.description += " + ";
    spec.description += t.equation;
    if (!t.expression.empty())
      sum += (sum.empty() ? "" : " + ") + std::string("(") + t.expression + ")";
    if (!t.phase_expression.empty())
      phase += (phase.empty() ? "" : " + ") + std::string("(") + t.phase_expression + ")";
    for (std::size_t i = 0; i < t.parameters.size(); ++i) {
      spec.parameters.push_back({t.parameters[i], t.units[i],
                                 std::clamp(t.start[i], t.lower[i], t.upper[i]), t.lower[i],
                                 t.upper[i], "fitted with the heartbeat model"});
    }
  }
  spec.expressions.clear();
  if (!sum.empty()) spec.expressions.emplace_back(kMotionHook, sum);
  if (!phase.empty()) spec.expressions.emplace_back(kPhaseHook, phase);
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  hw::WriteEffectFile(path, spec);
}

std::vector<MotionTerm> MotionTermLibrary(int harmonics, const MotionTermContext& context) {
  const double duration = std::max(context.duration_s, 1.0);
  const double dt = context.sample_period_s > 0.0 ? context.sample_period_s : 0.04;
  const double rate = context.rate_hz > 0.0 ? context.rate_hz : 1.2;
  // A period is only told from a trend (baseline_quadratic, amplitude_growth, rate_drift)
  // when at least 1.5 cycles lie within the trace.
  const double longest = duration / 1.5;
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
  MotionTerm step;
  step.kind = MotionTermKind::kBaselineStep;
  step.name = "baseline_step";
  AddTermParameter(step, "step_mm", "mm", 100.0);
  AddBoundedParameter(step, "step_time_s", "s", 0.5 * duration, 0.0, duration);
  const double widest = std::max(2.0 * dt, std::min(1.0, 0.1 * duration));
  AddBoundedParameter(step, "step_width_s", "s", 0.2, dt, widest);
  step.expression = "step_mm / (1 + exp(-(time_s - step_time_s) / step_width_s))";
  step.equation =
      "the baseline jumps by step_mm (mm) at step_time_s (s since start), rising over "
      "step_width_s (s): step_mm / (1 + exp(-(time_s - step_time_s) / step_width_s))";
  out.push_back(step);
  const std::string wave = "2 * pi * time_s / ";
  MotionTerm sine;
  sine.kind = MotionTermKind::kBaselineSine;
  sine.name = "baseline_sine";
  AddTermParameter(sine, "sine_cos_mm", "mm", 100.0);
  AddTermParameter(sine, "sine_sin_mm", "mm", 100.0);
  AddBoundedParameter(sine, "sine_period_s", "s", 0.5 * duration, std::max(1.5 / rate, 4.0 * dt),
                      longest);
  sine.expression =
      "sine_cos_mm * cos(" + wave + "sine_period_s) + sine_sin_mm * sin(" + wave + "sine_period_s)";
  sine.equation =
      "a slow periodic baseline: sine_cos_mm cos(2 pi time_s / sine_period_s) + sine_sin_mm "
      "sin(2 pi time_s / sine_period_s) (mm; period sine_period_s in s)";
  // A periodic term only where its shortest period leaves 1.5 cycles in the trace.
  const auto periodic = [&](const MotionTerm& t) {
    if (t.lower.back() < t.upper.back()) out.push_back(t);
  };
  periodic(sine);
  const double slow = std::max(3.0 / rate, 4.0 * dt);
  MotionTerm am;
  am.kind = MotionTermKind::kAmplitudeModulation;
  am.name = "amplitude_modulation";
  AddTermParameter(am, "modulation_cos", "1", 0.9);
  AddTermParameter(am, "modulation_sin", "1", 0.9);
  AddBoundedParameter(am, "modulation_period_s", "s", 0.5 * duration, slow, longest);
  am.expression = "heartbeat_mm * (modulation_cos * cos(" + wave +
                  "modulation_period_s) + modulation_sin * sin(" + wave + "modulation_period_s))";
  am.equation =
      "the beat's amplitude is modulated: heartbeat_mm (mm) * (modulation_cos cos(2 pi time_s / "
      "modulation_period_s) + modulation_sin sin(2 pi time_s / modulation_period_s)) "
      "(dimensionless depth, period modulation_period_s in s)";
  periodic(am);
  MotionTerm rm;
  rm.kind = MotionTermKind::kRateModulation;
  rm.name = "rate_modulation";
  AddTermParameter(rm, "rate_cos_hz", "Hz", 0.5);
  AddTermParameter(rm, "rate_sin_hz", "Hz", 0.5);
  AddBoundedParameter(rm, "rate_period_s", "s", 0.5 * duration, std::max(slow, 2.0), longest);
  rm.phase_expression = "rate_period_s * (rate_cos_hz * sin(" + wave +
                        "rate_period_s) - rate_sin_hz * cos(" + wave + "rate_period_s))";
  rm.equation =
      "the heart rate is modulated by a slow periodic signal: rate + rate_cos_hz cos(2 pi "
      "time_s / rate_period_s) + rate_sin_hz sin(2 pi time_s / rate_period_s) (Hz; period "
      "rate_period_s in s), i.e. phase_rad += rate_period_s * (rate_cos_hz sin(2 pi time_s / "
      "rate_period_s) - rate_sin_hz cos(2 pi time_s / rate_period_s))";
  periodic(rm);
  MotionTerm bt;
  bt.kind = MotionTermKind::kBeatTiming;
  bt.name = "beat_timing";
  bt.knot_spacing_s = std::max(1.5 / rate, 4.0 * dt);
  bt.penalty = 10.0;
  bt.penalty_first = 0;
  const int knots = static_cast<int>(std::ceil(duration / bt.knot_spacing_s - 1e-9)) + 1;
  for (int j = 0; j < knots; ++j) {
    const std::string name = "timing" + std::string(j < 10 ? "0" : "") + std::to_string(j) + "_rad";
    AddTermParameter(bt, name, "rad", 10.0);
    bt.phase_expression += (j == 0 ? "" : " + ") + name + " * max(0, 1 - abs(time_s - " +
                           MotionTermNumber(j * bt.knot_spacing_s) + ") / " +
                           MotionTermNumber(bt.knot_spacing_s) + ")";
  }
  bt.equation =
      "beat-to-beat timing changes: phase_rad += a piecewise-linear function of "
      "time_s, timing<j>_rad (rad) at time_s = j * " +
      MotionTermNumber(bt.knot_spacing_s) + " s";
  out.push_back(bt);
  return out;
}

MotionTermEvaluator::MotionTermEvaluator(const MotionTerm& term)
    : values_(MotionTermInputs().size() + term.parameters.size(), 0.0),
      phase_values_(MotionPhaseInputs().size() + term.parameters.size(), 0.0) {
  if (!term.expression.empty()) {
    expression_ = std::make_unique<hw::Expression>(
        term.expression, TermVariables(MotionTermInputs(), term), TermConstants());
  }
  if (!term.phase_expression.empty()) {
    phase_ = std::make_unique<hw::Expression>(
        term.phase_expression, TermVariables(MotionPhaseInputs(), term), TermConstants());
  }
}
MotionTermEvaluator::~MotionTermEvaluator() = default;
MotionTermEvaluator::MotionTermEvaluator(MotionTermEvaluator&&) noexcept = default;
MotionTermEvaluator& MotionTermEvaluator::operator=(MotionTermEvaluator&&) noexcept = default;

double MotionTermEvaluator::operator()(double time_s, double phase_rad, double rate_hz,
                                       double heartbeat_mm, const double* parameters) const {
  if (!expression_) return 0.0;
  values_[0] = time_s;
  values_[1] = phase_rad;
  values_[2] = rate_hz;
  values_[3] = heartbeat_mm;
  for (std::size_t i = 4; i < values_.size(); ++i) values_[i] = parameters[i - 4];
  return expression_->Evaluate(values_.data());
}

double MotionTermEvaluator::Phase(double time_s, const double* parameters) const {
  if (!phase_) return 0.0;
  phase_values_[0] = time_s;
  for (std::size_t i = 1; i < phase_values_.size(); ++i) phase_values_[i] = parameters[i - 1];
  return phase_->Evaluate(phase_values_.data());
}

}  // namespace echoservo::lab
