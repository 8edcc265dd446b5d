// Factories of the built-in catalog effects (one file each in hw/effects/), and the
// small base classes they share: their descriptive data (DescribedEffect, also for user
// effects) and their per-sample physics as whole-trial hooks (BatchedEffect).
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "hw/effect.h"

namespace echoservo::hw {

// Holds the name, texts, stage and parameter list so that an effect file only
// writes its physics.
class DescribedEffect : public Effect {
 public:
  DescribedEffect(std::string name, EffectStage stage, std::string description,
                  std::string signature, std::vector<ParameterSpec> parameters)
      : name_(std::move(name)),
        stage_(stage),
        description_(std::move(description)),
        signature_(std::move(signature)),
        parameters_(std::move(parameters)) {}
  std::string_view name() const final { return name_; }
  std::string_view description() const final { return description_; }
  std::string_view signature() const final { return signature_; }
  EffectStage stage() const final { return stage_; }
  std::span<const ParameterSpec> parameters() const final { return parameters_; }

 private:
  std::string name_;
  EffectStage stage_;
  std::string description_;
  std::string signature_;
  std::vector<ParameterSpec> parameters_;
};

// The base of every built-in effect. The per-sample physics is a static function of the
// effect class, FrictionN(speed_mm_s, c, p) or OffsetMm(friction_force_n, c, p) (neutral
// when the class has none); this base turns each into both the per-sample and the
// whole-trial hook, so the two cannot disagree and a trial costs one virtual call per effect.
template <class Self>
class BatchedEffect : public DescribedEffect {
 public:
  using DescribedEffect::DescribedEffect;
  static double FrictionN(double, const EffectContext&, const double*) { return 0.0; }
  static double OffsetMm(double, const EffectContext&, const double*) { return 0.0; }

 protected:
  double DoFrictionMagnitudeN(double speed_mm_s, const EffectContext& c,
                              const double* p) const final {
    return Self::FrictionN(speed_mm_s, c, p);
  }
  double DoDriveOffsetMm(double friction_force_n, const EffectContext& c,
                         const double* p) const final {
    return Self::OffsetMm(friction_force_n, c, p);
  }
  // An effect without a friction (offset) function adds nothing to any sample: its
  // whole-trial hook returns at once instead of adding zero to every sample.
  void DoAddFrictionMagnitudesN(std::span<const double> speed_mm_s, const EffectContext& c,
                                const double* p, std::span<double> out) const final {
    if constexpr (&Self::FrictionN != &BatchedEffect::FrictionN) {
      for (std::size_t i = 0; i < out.size(); ++i) out[i] += Self::FrictionN(speed_mm_s[i], c, p);
    }
  }
  void DoAddDriveOffsetsMm(std::span<const double> friction_force_n, const EffectContext& c,
                           const double* p, std::span<double> drive_mm) const final {
    if constexpr (&Self::OffsetMm != &BatchedEffect::OffsetMm) {
      for (std::size_t i = 0; i < drive_mm.size(); ++i)
        drive_mm[i] += Self::OffsetMm(friction_force_n[i], c, p);
    }
  }
};

std::unique_ptr<Effect> MakeCoulombFriction();
std::unique_ptr<Effect> MakeViscousFriction();
std::unique_ptr<Effect> MakeStribeckFriction();
std::unique_ptr<Effect> MakeCapstanFriction();
std::unique_ptr<Effect> MakeGuidewireCompliance();
std::unique_ptr<Effect> MakeBacklash();
std::unique_ptr<Effect> MakeFrictionBacklash();
std::unique_ptr<Effect> MakeDeadzoneTraversal();
std::unique_ptr<Effect> MakeSensorDelay();
std::unique_ptr<Effect> MakeTipSensorScale();

}  // namespace echoservo::hw
