// Factories of the built-in catalog effects (one file each in hw/effects/), and the
// small base class they share for their descriptive data.
#pragma once

#include <memory>
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
