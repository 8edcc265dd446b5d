// A named physical effect of the guidewire–sheath transmission.
//
// The catheter model (hw/transmission_model.h) is a fixed pipeline of stages: friction
// force (N) → drive position (mm) → deadzone width (mm) → tip dynamics → tip sensor. An
// Effect contributes through the hooks below, each with a neutral default. Effects are
// stateless: parameters arrive as a block of doubles (`p`, laid out as parameters()) and all
// state lives in the model, so the simulator and the model lab share one implementation.
// Units: mm, s, N, rad. Positive base motion pushes the guidewire towards the tip.
// Signal hooks (SignalFrictionN, ForceN, SensorOffsetMm) also see where the base is, how
// fast it moves and accelerates and how long the trial has run (SampleSignals); an effect
// that overrides one says so with UsesSignals(), and the model skips the signal paths
// entirely when no effect does (the built-in effects use none). The deadzone width has its
// own signal hook (SignalBacklashWidthMm: a width that changes with the motion, e.g. a
// guidewire that lifts off the bend wall when fast, B(v) = θ·gap·(1 + |v|/v0)), declared by
// UsesSignalBacklash(); the model's per-sample width passes the static width
// (BacklashWidthMm, all effects) through it in pipeline order, and with no such effect the
// width stays one number per trial.
// Extension: derive, override the protected Do* hooks, describe the parameters, register a
// factory.
// Details: docs/adding_an_effect.md#1-choose-the-physics-and-the-stage-hooks
#pragma once

#include <cassert>
#include <cstddef>
#include <span>
#include <string>
#include <string_view>

#include "formats/catheter_config.h"

namespace echoservo::hw {

// One fitted/simulated parameter of an effect.
struct ParameterSpec {
  std::string name;      // e.g. "f0_n"; fully qualified as "<effect>.<name>"
  std::string unit;      // e.g. "N", "N/(mm/s)", "s", "1"
  double default_value;  // typical physical value (simulator default, fit start)
  double lower;          // physical bounds used to validate and to bound fits
  double upper;
  std::string doc;
};

// Which part of the pipeline an effect acts on (for reports and diagnosis).
enum class EffectStage { kFriction, kCompliance, kBacklash, kTipDynamics, kSensor };
std::string_view ToString(EffectStage stage);

// Geometry seen by every hook, derived once from CatheterConfig.
struct EffectContext {
  double total_bend_rad = 0.0;  // θ
  double gap_mm = 0.0;          // D_sheath − D_guidewire
  double tip_load_n = 0.0;      // normal force near the tip
  static EffectContext From(const formats::CatheterConfig& config);
};

// What a signal hook sees of one sample besides the geometry. time_s counts from the
// trial's first sample (lab) or the simulation's last reset (simulated catheter).
struct SampleSignals {
  double time_s = 0.0;
  double base_mm = 0.0;
  double velocity_mm_s = 0.0;  // signed
  double acceleration_mm_s2 = 0.0;
};

// The same over a whole trial: spans of equal length (checked by the users, asserted).
struct TrialSignals {
  std::span<const double> time_s, base_mm, velocity_mm_s, acceleration_mm_s2;
  std::size_t size() const { return time_s.size(); }
  bool Consistent() const {
    return base_mm.size() == size() && velocity_mm_s.size() == size() &&
           acceleration_mm_s2.size() == size();
  }
  SampleSignals At(std::size_t i) const {
    return {time_s[i], base_mm[i], velocity_mm_s[i], acceleration_mm_s2[i]};
  }
};

class Effect {
 public:
  virtual ~Effect() = default;
  Effect(const Effect&) = delete;
  Effect& operator=(const Effect&) = delete;

  virtual std::string_view name() const = 0;
  // One paragraph: the physics and the equation.
  virtual std::string_view description() const = 0;
  // What the effect looks like in measured data (used by `lab diagnose`).
  virtual std::string_view signature() const = 0;
  virtual EffectStage stage() const = 0;
  virtual std::span<const ParameterSpec> parameters() const = 0;

  // Friction magnitude (N, >= 0) added at base speed |v| (mm/s).
  double FrictionMagnitudeN(double speed_mm_s, const EffectContext& c, const double* p) const {
    return DoFrictionMagnitudeN(speed_mm_s, c, p);
  }
  // Multiplier (>= 0) applied to the summed friction magnitude.
  double FrictionScale(const EffectContext& c, const double* p) const {
    return DoFrictionScale(c, p);
  }
  // Offset (mm) added to the base position to give the drive position, given the
  // signed friction force the guidewire carries.
  double DriveOffsetMm(double friction_force_n, const EffectContext& c, const double* p) const {
    return DoDriveOffsetMm(friction_force_n, c, p);
  }
  // The two per-sample hooks over a whole trial, one virtual call per effect:
  // out[i] += FrictionMagnitudeN(speed_mm_s[i]) and drive_mm[i] += DriveOffsetMm(force[i]).
  // Spans of equal length (asserted).
  void AddFrictionMagnitudesN(std::span<const double> speed_mm_s, const EffectContext& c,
                              const double* p, std::span<double> out) const {
    assert(speed_mm_s.size() == out.size());
    DoAddFrictionMagnitudesN(speed_mm_s, c, p, out);
  }
  void AddDriveOffsetsMm(std::span<const double> friction_force_n, const EffectContext& c,
                         const double* p, std::span<double> drive_mm) const {
    assert(friction_force_n.size() == drive_mm.size());
    DoAddDriveOffsetsMm(friction_force_n, c, p, drive_mm);
  }
  // Deadzone width (mm) after this effect, from the width so far and the friction level
  // (the breakaway friction magnitude, N).
  double BacklashWidthMm(double width_mm, double friction_level_n, const EffectContext& c,
                         const double* p) const {
    return DoBacklashWidthMm(width_mm, friction_level_n, c, p);
  }
  // Time constant (s) with which the tip approaches the band the deadzone allows; 0: instant.
  double TraversalTimeConstantS(const double* p) const { return DoTraversalTimeConstantS(p); }
  // Tip sensor: extra latency (s) and gain.
  double SensorDelayS(const double* p) const { return DoSensorDelayS(p); }
  double SensorScale(const double* p) const { return DoSensorScale(p); }

  // Whether the effect overrides a signal hook below (false: they are all neutral and the
  // model never calls them).
  bool UsesSignals() const { return DoUsesSignals(); }
  // Extra friction magnitude (N, >= 0) at base speed |v| (mm/s) that may depend on the
  // signals; added to FrictionMagnitudeN's sum before the friction scale.
  double SignalFrictionN(double speed_mm_s, const SampleSignals& s, const EffectContext& c,
                         const double* p) const {
    return DoSignalFrictionN(speed_mm_s, s, c, p);
  }
  // Multiplier (>= 0) of the whole friction magnitude (plain and signal friction, after
  // FrictionScale) that may depend on the signals: friction that grows as a trial runs.
  double SignalFrictionScale(const SampleSignals& s, const EffectContext& c,
                             const double* p) const {
    return DoSignalFrictionScale(s, c, p);
  }
  // A signed force (N, positive along +base) the base must overcome besides friction and
  // that the force sensor reads with it (guidewire inertia m·a, a spring k·x). It takes no
  // part in stick/slip.
  double ForceN(const SampleSignals& s, const EffectContext& c, const double* p) const {
    return DoForceN(s, c, p);
  }
  // Offset (mm) added to the tip sensor's reading of the (delayed) tip position tip_mm.
  double SensorOffsetMm(double tip_mm, const SampleSignals& s, const EffectContext& c,
                        const double* p) const {
    return DoSensorOffsetMm(tip_mm, s, c, p);
  }
  // Whether the effect overrides SignalBacklashWidthMm (independent of UsesSignals: false,
  // the model never calls it and the width is the static one).
  bool UsesSignalBacklash() const { return DoUsesSignalBacklash(); }
  // Deadzone width (mm) after this effect at one sample, from the width so far (the static
  // width, BacklashWidthMm of every effect, then the signal hooks of the effects before this
  // one), the friction level (N, as for BacklashWidthMm) and the sample's signals.
  double SignalBacklashWidthMm(double width_mm, double friction_level_n, const SampleSignals& s,
                               const EffectContext& c, const double* p) const {
    return DoSignalBacklashWidthMm(width_mm, friction_level_n, s, c, p);
  }
  // Whole-trial form: width_mm[i] = SignalBacklashWidthMm(width_mm[i], friction_level_n,
  // s.At(i)). Spans of equal length (asserted).
  void SignalBacklashWidthsMm(double friction_level_n, const TrialSignals& s,
                              const EffectContext& c, const double* p,
                              std::span<double> width_mm) const {
    assert(s.size() == width_mm.size() && s.Consistent());
    DoSignalBacklashWidthsMm(friction_level_n, s, c, p, width_mm);
  }
  // Whole-trial forms: out[i] += SignalFrictionN(speed_mm_s[i], s.At(i)) and
  // force_n[i] += ForceN(s.At(i)). Spans of equal length (asserted).
  void AddSignalFrictionsN(std::span<const double> speed_mm_s, const TrialSignals& s,
                           const EffectContext& c, const double* p, std::span<double> out) const {
    assert(speed_mm_s.size() == out.size() && s.size() == out.size() && s.Consistent());
    DoAddSignalFrictionsN(speed_mm_s, s, c, p, out);
  }
  void AddForcesN(const TrialSignals& s, const EffectContext& c, const double* p,
                  std::span<double> force_n) const {
    assert(s.size() == force_n.size() && s.Consistent());
    DoAddForcesN(s, c, p, force_n);
  }

 protected:
  Effect() = default;
  virtual double DoFrictionMagnitudeN(double, const EffectContext&, const double*) const {
    return 0.0;
  }
  virtual double DoFrictionScale(const EffectContext&, const double*) const { return 1.0; }
  virtual double DoDriveOffsetMm(double, const EffectContext&, const double*) const { return 0.0; }
  virtual double DoBacklashWidthMm(double width_mm, double, const EffectContext&,
                                   const double*) const {
    return width_mm;
  }
  // Whole-trial hooks: by default the per-sample hook for each sample (built-in effects
  // override both at once through BatchedEffect, hw/effects/builtin_effects.h).
  virtual void DoAddFrictionMagnitudesN(std::span<const double> speed_mm_s, const EffectContext& c,
                                        const double* p, std::span<double> out) const {
    for (std::size_t i = 0; i < out.size(); ++i)
      out[i] += DoFrictionMagnitudeN(speed_mm_s[i], c, p);
  }
  virtual void DoAddDriveOffsetsMm(std::span<const double> friction_force_n, const EffectContext& c,
                                   const double* p, std::span<double> drive_mm) const {
    for (std::size_t i = 0; i < drive_mm.size(); ++i)
      drive_mm[i] += DoDriveOffsetMm(friction_force_n[i], c, p);
  }
  virtual double DoTraversalTimeConstantS(const double*) const { return 0.0; }
  virtual double DoSensorDelayS(const double*) const { return 0.0; }
  virtual double DoSensorScale(const double*) const { return 1.0; }
  virtual bool DoUsesSignals() const { return false; }
  virtual double DoSignalFrictionN(double, const SampleSignals&, const EffectContext&,
                                   const double*) const {
    return 0.0;
  }
  virtual double DoSignalFrictionScale(const SampleSignals&, const EffectContext&,
                                       const double*) const {
    return 1.0;
  }
  virtual double DoForceN(const SampleSignals&, const EffectContext&, const double*) const {
    return 0.0;
  }
  virtual double DoSensorOffsetMm(double, const SampleSignals&, const EffectContext&,
                                  const double*) const {
    return 0.0;
  }
  virtual bool DoUsesSignalBacklash() const { return false; }
  virtual double DoSignalBacklashWidthMm(double width_mm, double, const SampleSignals&,
                                         const EffectContext&, const double*) const {
    return width_mm;
  }
  virtual void DoSignalBacklashWidthsMm(double friction_level_n, const TrialSignals& s,
                                        const EffectContext& c, const double* p,
                                        std::span<double> width_mm) const {
    for (std::size_t i = 0; i < width_mm.size(); ++i)
      width_mm[i] = DoSignalBacklashWidthMm(width_mm[i], friction_level_n, s.At(i), c, p);
  }
  virtual void DoAddSignalFrictionsN(std::span<const double> speed_mm_s, const TrialSignals& s,
                                     const EffectContext& c, const double* p,
                                     std::span<double> out) const {
    for (std::size_t i = 0; i < out.size(); ++i)
      out[i] += DoSignalFrictionN(speed_mm_s[i], s.At(i), c, p);
  }
  virtual void DoAddForcesN(const TrialSignals& s, const EffectContext& c, const double* p,
                            std::span<double> force_n) const {
    for (std::size_t i = 0; i < force_n.size(); ++i) force_n[i] += DoForceN(s.At(i), c, p);
  }
};

}  // namespace echoservo::hw
