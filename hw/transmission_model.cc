#include "hw/transmission_model.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>

namespace echoservo::hw {

TransmissionModel::TransmissionModel(const EffectRegistry& registry,
                                     const std::vector<std::string>& effects,
                                     const formats::CatheterConfig& config)
    : config_(config) {
  config_.Validate();
  for (const std::string& name : effects) {
    if (HasEffect(name)) throw std::invalid_argument("effect '" + name + "' listed twice");
    effects_.push_back(registry.Create(name));
    names_.push_back(name);
    offsets_.push_back(params_.size());
    for (const ParameterSpec& spec : effects_.back()->parameters()) {
      info_.push_back({name + "." + spec.name, effects_.size() - 1, spec});
      params_.push_back(spec.default_value);
    }
  }
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    if (effects_[e]->UsesSignals()) signal_effects_.push_back(e);
  }
  uses_signals_ = !signal_effects_.empty();
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    if (effects_[e]->UsesSignalBacklash()) signal_backlash_effects_.push_back(e);
  }
  uses_signal_backlash_ = !signal_backlash_effects_.empty();
  context_ = EffectContext::From(config_);
  Refresh();
}

TransmissionModel::TransmissionModel(TransmissionModel&&) noexcept = default;
TransmissionModel& TransmissionModel::operator=(TransmissionModel&&) noexcept = default;
TransmissionModel::~TransmissionModel() = default;

bool TransmissionModel::HasEffect(std::string_view name) const {
  return std::find(names_.begin(), names_.end(), name) != names_.end();
}

void TransmissionModel::set_config(const formats::CatheterConfig& config) {
  config.Validate();
  config_ = config;
  context_ = EffectContext::From(config_);
  Refresh();
}

void TransmissionModel::set_parameters(const std::vector<double>& values) {
  if (values.size() != params_.size()) {
    throw std::invalid_argument("model parameters: expected " + std::to_string(params_.size()) +
                                " values, got " + std::to_string(values.size()));
  }
  for (std::size_t i = 0; i < values.size(); ++i) {
    const ParameterSpec& s = info_[i].spec;
    if (!std::isfinite(values[i]) || values[i] < s.lower || values[i] > s.upper) {
      throw std::invalid_argument("model parameter '" + info_[i].qualified_name +
                                  "' = " + std::to_string(values[i]) + " is outside [" +
                                  std::to_string(s.lower) + ", " + std::to_string(s.upper) + "] " +
                                  s.unit);
    }
  }
  params_ = values;
  Refresh();
}

void TransmissionModel::SetParametersForFit(const double* values) {
  for (std::size_t i = 0; i < params_.size(); ++i) {
    assert(std::isfinite(values[i]));
    params_[i] = values[i];
  }
  Refresh();
}

void TransmissionModel::SetParameter(std::string_view name, double value) {
  std::vector<double> values = params_;
  for (std::size_t i = 0; i < info_.size(); ++i) {
    if (info_[i].qualified_name == name) {
      values[i] = value;
      set_parameters(values);
      return;
    }
  }
  throw std::invalid_argument("unknown model parameter '" + std::string(name) +
                              "' (expected <effect>.<parameter> of an effect in the model)");
}

double TransmissionModel::GetParameter(std::string_view name) const {
  for (std::size_t i = 0; i < info_.size(); ++i) {
    if (info_[i].qualified_name == name) return params_[i];
  }
  throw std::invalid_argument("unknown model parameter '" + std::string(name) + "'");
}

double TransmissionModel::FrictionMagnitudeN(double speed_mm_s) const {
  double sum = 0.0;
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    sum += effects_[e]->FrictionMagnitudeN(speed_mm_s, context_, params_.data() + offsets_[e]);
  }
  return sum * friction_scale_;
}

double TransmissionModel::DriveMm(double base_mm, double friction_force_n) const {
  double drive = base_mm;
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    drive += effects_[e]->DriveOffsetMm(friction_force_n, context_, params_.data() + offsets_[e]);
  }
  return drive;
}

void TransmissionModel::FrictionMagnitudesN(std::span<const double> speed_mm_s,
                                            std::span<double> out) const {
  assert(speed_mm_s.size() == out.size());
  std::fill(out.begin(), out.end(), 0.0);
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    effects_[e]->AddFrictionMagnitudesN(speed_mm_s, context_, params_.data() + offsets_[e], out);
  }
  for (double& f : out) f *= friction_scale_;
}

void TransmissionModel::DrivesMm(std::span<const double> base_mm,
                                 std::span<const double> friction_force_n,
                                 std::span<double> drive_mm) const {
  assert(base_mm.size() == drive_mm.size() && friction_force_n.size() == drive_mm.size());
  std::copy(base_mm.begin(), base_mm.end(), drive_mm.begin());
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    effects_[e]->AddDriveOffsetsMm(friction_force_n, context_, params_.data() + offsets_[e],
                                   drive_mm);
  }
}

double TransmissionModel::FrictionMagnitudeN(double speed_mm_s, const SampleSignals& s) const {
  if (!uses_signals_) return FrictionMagnitudeN(speed_mm_s);
  double sum = 0.0;
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    const double* p = params_.data() + offsets_[e];
    sum += effects_[e]->FrictionMagnitudeN(speed_mm_s, context_, p);
    if (effects_[e]->UsesSignals()) sum += effects_[e]->SignalFrictionN(speed_mm_s, s, context_, p);
  }
  return sum * friction_scale_ * SignalFrictionScale(s);
}

double TransmissionModel::SignalFrictionScale(const SampleSignals& s) const {
  double scale = 1.0;
  if (!uses_signals_) return scale;
  for (const std::size_t e : signal_effects_) {
    scale *= effects_[e]->SignalFrictionScale(s, context_, params_.data() + offsets_[e]);
  }
  return scale;
}

double TransmissionModel::BreakawayN(const SampleSignals& s) const {
  if (!uses_signals_) return friction_level_n_;
  double sum = 0.0;
  for (const std::size_t e : signal_effects_) {
    sum += effects_[e]->SignalFrictionN(0.0, s, context_, params_.data() + offsets_[e]);
  }
  return (friction_level_n_ + sum * friction_scale_) * SignalFrictionScale(s);
}

double TransmissionModel::ForceN(const SampleSignals& s) const {
  double sum = 0.0;
  if (!uses_signals_) return sum;
  for (const std::size_t e : signal_effects_) {
    sum += effects_[e]->ForceN(s, context_, params_.data() + offsets_[e]);
  }
  return sum;
}

double TransmissionModel::SensorOffsetMm(double tip_mm, const SampleSignals& s) const {
  double sum = 0.0;
  if (!uses_signals_) return sum;
  for (const std::size_t e : signal_effects_) {
    sum += effects_[e]->SensorOffsetMm(tip_mm, s, context_, params_.data() + offsets_[e]);
  }
  return sum;
}

void TransmissionModel::FrictionMagnitudesN(std::span<const double> speed_mm_s,
                                            const TrialSignals& s, std::span<double> out) const {
  assert(speed_mm_s.size() == out.size() && s.size() == out.size() && s.Consistent());
  if (!uses_signals_) return FrictionMagnitudesN(speed_mm_s, out);
  std::fill(out.begin(), out.end(), 0.0);
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    const double* p = params_.data() + offsets_[e];
    effects_[e]->AddFrictionMagnitudesN(speed_mm_s, context_, p, out);
    if (effects_[e]->UsesSignals())
      effects_[e]->AddSignalFrictionsN(speed_mm_s, s, context_, p, out);
  }
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] *= friction_scale_ * SignalFrictionScale(s.At(i));
}

void TransmissionModel::BreakawaysN(const TrialSignals& s, std::span<double> out) const {
  assert(s.size() == out.size() && s.Consistent());
  std::fill(out.begin(), out.end(), 0.0);
  if (uses_signals_) {
    // Signal friction at rest: the speeds are all zero.
    const std::vector<double> rest(out.size(), 0.0);
    for (const std::size_t e : signal_effects_) {
      effects_[e]->AddSignalFrictionsN(rest, s, context_, params_.data() + offsets_[e], out);
    }
  }
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = friction_level_n_ + out[i] * friction_scale_;
    if (uses_signals_) out[i] *= SignalFrictionScale(s.At(i));
  }
}

void TransmissionModel::AddForcesN(const TrialSignals& s, std::span<double> force_n) const {
  assert(s.size() == force_n.size() && s.Consistent());
  if (!uses_signals_) return;
  for (const std::size_t e : signal_effects_) {
    effects_[e]->AddForcesN(s, context_, params_.data() + offsets_[e], force_n);
  }
}

void TransmissionModel::AddSensorOffsetsMm(std::span<double> tip_mm, const TrialSignals& s) const {
  assert(s.size() == tip_mm.size() && s.Consistent());
  if (!uses_signals_) return;
  for (std::size_t i = 0; i < tip_mm.size(); ++i) tip_mm[i] += SensorOffsetMm(tip_mm[i], s.At(i));
}

double TransmissionModel::BacklashWidthMm(const SampleSignals& s) const {
  double width = width_mm_;
  if (!uses_signal_backlash_) return width;
  for (const std::size_t e : signal_backlash_effects_) {
    width = effects_[e]->SignalBacklashWidthMm(width, friction_level_n_, s, context_,
                                               params_.data() + offsets_[e]);
  }
  return width > 0.0 ? width : 0.0;  // also maps NaN to 0
}

void TransmissionModel::BacklashWidthsMm(const TrialSignals& s, std::span<double> out) const {
  assert(s.size() == out.size() && s.Consistent());
  std::fill(out.begin(), out.end(), width_mm_);
  if (!uses_signal_backlash_) return;
  for (const std::size_t e : signal_backlash_effects_) {
    effects_[e]->SignalBacklashWidthsMm(friction_level_n_, s, context_,
                                        params_.data() + offsets_[e], out);
  }
  for (double& w : out) w = w > 0.0 ? w : 0.0;
}

double TransmissionModel::StepTip(double tip_mm, double drive_mm, double dt_s) const {
  return StepTipWithFraction(tip_mm, drive_mm, TraversalFraction(dt_s));
}

void TransmissionModel::Refresh() {
  friction_scale_ = 1.0;
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    friction_scale_ *= effects_[e]->FrictionScale(context_, params_.data() + offsets_[e]);
  }
  friction_level_n_ = FrictionMagnitudeN(0.0);
  width_mm_ = 0.0;
  tau_s_ = 0.0;
  delay_s_ = 0.0;
  scale_ = 1.0;
  for (std::size_t e = 0; e < effects_.size(); ++e) {
    const double* p = params_.data() + offsets_[e];
    width_mm_ = effects_[e]->BacklashWidthMm(width_mm_, friction_level_n_, context_, p);
    tau_s_ = std::max(tau_s_, effects_[e]->TraversalTimeConstantS(p));
    delay_s_ += effects_[e]->SensorDelayS(p);
    scale_ *= effects_[e]->SensorScale(p);
  }
  assert(width_mm_ >= 0.0 && friction_scale_ >= 0.0);
}

}  // namespace echoservo::hw
