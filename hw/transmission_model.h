// The guidewire–sheath transmission as a composition of catalog effects.
//
// One model serves both the simulated plant (hw/simulated_catheter.h) and the model lab:
// it holds the chosen effects, a flat parameter vector (each effect's block, named
// "<effect>.<parameter>"), and the catheter geometry, and evaluates the pipeline
//   friction magnitude(|v|) → drive = base + offsets(F) → deadzone width → tip update
//   → tip sensor (delay, gain).
// Effects with signal hooks (hw/effect.h: UsesSignals) add, per sample, friction that
// depends on the signals, a signed extra force (ForceN) and a sensor offset; the
// functions taking SampleSignals/TrialSignals include them, the others never call them,
// and with no such effect the signal forms equal the plain ones. Effects with a signal
// backlash hook (UsesSignalBacklash) make the deadzone width per sample:
// BacklashWidthMm(s) and the StepTip forms taking the half-width explicitly.
// Units: mm, s, N. Positions are along the catheter axis in the base frame.
#pragma once

#include <algorithm>
#include <cmath>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "hw/effect_registry.h"

namespace echoservo::hw {

struct ParameterInfo {
  std::string qualified_name;  // "<effect>.<parameter>"
  std::size_t effect_index;
  ParameterSpec spec;
};

class TransmissionModel {
 public:
  // Throws std::invalid_argument for unknown effects or an invalid geometry.
  TransmissionModel(const EffectRegistry& registry, const std::vector<std::string>& effects,
                    const formats::CatheterConfig& config);
  TransmissionModel(TransmissionModel&&) noexcept;
  TransmissionModel& operator=(TransmissionModel&&) noexcept;
  ~TransmissionModel();

  const std::vector<std::string>& effect_names() const { return names_; }
  bool HasEffect(std::string_view name) const;
  const formats::CatheterConfig& config() const { return config_; }
  void set_config(const formats::CatheterConfig& config);

  const std::vector<ParameterInfo>& parameter_info() const { return info_; }
  const std::vector<double>& parameters() const { return params_; }
  // Throws std::invalid_argument on a wrong size, a non-finite value or one outside the
  // parameter's physical bounds (naming it).
  void set_parameters(const std::vector<double>& values);
  // For fitters: sets num_parameters() values without the bounds check (numeric
  // differentiation may probe just outside a bound). Values must be finite (asserted).
  void SetParametersForFit(const double* values);
  // `name` is "<effect>.<parameter>"; throws for an unknown name or an out-of-bounds value.
  void SetParameter(std::string_view name, double value);
  double GetParameter(std::string_view name) const;

  // Friction magnitude (N, >= 0) at base speed |v| (mm/s), all terms and scales.
  double FrictionMagnitudeN(double speed_mm_s) const;
  // Breakaway friction (magnitude at rest), the "friction level" of the configuration.
  double FrictionLevelN() const { return friction_level_n_; }
  // Mean slope of friction against speed over 0–100 mm/s (N/(mm/s)): the viscous term a
  // Coulomb + viscous calibration would see.
  double ViscousSlopeNPerMmS() const {
    return (FrictionMagnitudeN(100.0) - friction_level_n_) / 100.0;
  }
  // Drive (guidewire tip-end) position for a base position and the signed friction force.
  double DriveMm(double base_mm, double friction_force_n) const;
  // The same two over a whole trial (spans of equal length, asserted), one virtual call per
  // effect; equal to the per-sample calls, bit for bit.
  void FrictionMagnitudesN(std::span<const double> speed_mm_s, std::span<double> out) const;
  void DrivesMm(std::span<const double> base_mm, std::span<const double> friction_force_n,
                std::span<double> drive_mm) const;
  // Signal forms (hw/effect.h). FrictionMagnitudeN(speed, s): plain plus signal friction,
  // scaled. BreakawayN(s): FrictionLevelN() + scaled signal friction at speed 0. ForceN:
  // the sum of the effects' signed forces. SensorOffsetMm: the sum of the sensor offsets
  // at the delayed tip position `tip_mm`. All equal the plain forms (0 for ForceN and
  // SensorOffsetMm) when no effect uses signals.
  bool UsesSignals() const { return uses_signals_; }
  double FrictionMagnitudeN(double speed_mm_s, const SampleSignals& s) const;
  double BreakawayN(const SampleSignals& s) const;
  // Product of the effects' signal friction scales at `s` (1 without signal effects).
  double SignalFrictionScale(const SampleSignals& s) const;
  double ForceN(const SampleSignals& s) const;
  double SensorOffsetMm(double tip_mm, const SampleSignals& s) const;
  // Whole-trial signal forms (spans of the signals' length, asserted): out[i] =
  // FrictionMagnitudeN(speed[i], s.At(i)), out[i] = BreakawayN(s.At(i)), force[i] +=
  // ForceN(s.At(i)) and tip[i] += SensorOffsetMm(tip[i], s.At(i)).
  void FrictionMagnitudesN(std::span<const double> speed_mm_s, const TrialSignals& s,
                           std::span<double> out) const;
  void BreakawaysN(const TrialSignals& s, std::span<double> out) const;
  void AddForcesN(const TrialSignals& s, std::span<double> force_n) const;
  void AddSensorOffsetsMm(std::span<double> tip_mm, const TrialSignals& s) const;

  // The static deadzone width (mm): every effect's BacklashWidthMm in pipeline order.
  double BacklashWidthMm() const { return width_mm_; }
  // Whether the width changes with the signals (an effect uses SignalBacklashWidthMm).
  bool UsesSignalBacklash() const { return uses_signal_backlash_; }
  // The width (mm, >= 0) at one sample: the static width through every signal-backlash
  // effect's SignalBacklashWidthMm in pipeline order (with the friction level
  // FrictionLevelN()), negative → 0. BacklashWidthMm() exactly without such effects.
  double BacklashWidthMm(const SampleSignals& s) const;
  // The same over a whole trial: out[i] = BacklashWidthMm(s.At(i)) (spans of the signals'
  // length, asserted), one virtual call per signal-backlash effect.
  void BacklashWidthsMm(const TrialSignals& s, std::span<double> out) const;
  double TraversalTimeConstantS() const { return tau_s_; }
  double SensorDelayS() const { return delay_s_; }
  double SensorScale() const { return scale_; }

  // One tip update over dt: the tip stays inside the band [drive - B/2, drive + B/2];
  // outside it, it moves to the band edge at once or, with deadzone traversal, as a
  // first-order lag with time constant τ.
  double StepTip(double tip_mm, double drive_mm, double dt_s) const;
  // The same with the band's half-width (mm) given: 0.5·BacklashWidthMm(s) of the sample
  // where the width changes with the signals.
  double StepTip(double tip_mm, double drive_mm, double dt_s, double half_width_mm) const {
    return StepTipWithFraction(tip_mm, drive_mm, TraversalFraction(dt_s), half_width_mm);
  }
  // The same with the traversal fraction 1 − exp(−dt/τ) precomputed by the caller
  // (TraversalFraction(dt)), for loops over uniformly sampled data.
  double TraversalFraction(double dt_s) const {
    return tau_s_ > 0.0 ? 1.0 - std::exp(-dt_s / tau_s_) : 1.0;
  }
  double StepTipWithFraction(double tip_mm, double drive_mm, double fraction) const {
    return StepTipWithFraction(tip_mm, drive_mm, fraction, 0.5 * width_mm_);
  }
  double StepTipWithFraction(double tip_mm, double drive_mm, double fraction,
                             double half_width_mm) const {
    const double target = std::clamp(tip_mm, drive_mm - half_width_mm, drive_mm + half_width_mm);
    return tip_mm + (target - tip_mm) * fraction;
  }

 private:
  void Refresh();
  std::vector<std::string> names_;
  std::vector<std::unique_ptr<Effect>> effects_;
  std::vector<std::size_t> offsets_;
  std::vector<ParameterInfo> info_;
  std::vector<double> params_;
  formats::CatheterConfig config_;
  EffectContext context_;
  double friction_scale_ = 1.0;
  double friction_level_n_ = 0.0;
  double width_mm_ = 0.0;
  double tau_s_ = 0.0;
  double delay_s_ = 0.0;
  double scale_ = 1.0;
  bool uses_signals_ = false;
  std::vector<std::size_t> signal_effects_;  // indices of the effects that use signals
  bool uses_signal_backlash_ = false;
  std::vector<std::size_t> signal_backlash_effects_;  // ... that use signal backlash
};

}  // namespace echoservo::hw
