#include "apps/commands/plant_flags.h"

#include <CLI/CLI.hpp>

#include "apps/output.h"
#include "hw/effect_registry.h"

namespace echoservo::apps {

std::vector<std::string> PlantFlags::Effects() const {
  if (effects.empty()) return {};
  return hw::ParseModelSpec(effects, hw::EffectRegistry::WithBuiltinEffects());
}

std::vector<std::pair<std::string, double>> PlantFlags::Parameters() const {
  std::vector<std::pair<std::string, double>> out;
  for (const std::string& s : sets) out.push_back(ParseAssignment(s));
  return out;
}

void AddPlantFlags(CLI::App* app, PlantFlags& flags) {
  app->add_option("--effects", flags.effects,
                  "Effects of the simulated catheter as a model SPEC, e.g. seed+capstan_friction "
                  "(see `echoservo sim effects`)");
  app->add_option(
      "--set", flags.sets,
      "Override an effect parameter, e.g. --set deadzone_traversal.tau_s=0.01 (repeatable)");
  app->add_option("--seed", flags.seed, "Sensor-noise seed");
}

}  // namespace echoservo::apps
