#include "apps/commands/plant_flags.h"

#include <CLI/CLI.hpp>

#include "apps/output.h"
#include "hw/effect_registry.h"

namespace echoservo::apps {

std::vector<std::string> PlantFlags::Effects() const {
  hw::EffectRegistry& registry = BuildCatalog(catalog);
  if (effects.empty()) return {};
  return hw::ResolveModelSpec(effects, registry);
}

const hw::EffectRegistry& PlantFlags::Registry() const { return BuildCatalog(catalog); }

std::vector<std::pair<std::string, double>> PlantFlags::Parameters() const {
  std::vector<std::pair<std::string, double>> out;
  for (const std::string& s : sets) out.push_back(ParseAssignment(s));
  return out;
}

void AddPlantFlags(CLI::App* app, PlantFlags& flags) {
  app->add_option("--effects", flags.effects,
                  "Effects of the simulated catheter as a model SPEC, e.g. seed+capstan_friction "
                  "or seed+@my_effect.json (see `echoservo sim effects`, docs/effect_files.md)");
  AddCatalogFlags(app, flags.catalog);
  app->add_option(
      "--set", flags.sets,
      "Override an effect parameter, e.g. --set deadzone_traversal.tau_s=0.01 (repeatable)");
  app->add_option("--seed", flags.seed, "Sensor-noise seed");
}

}  // namespace echoservo::apps
