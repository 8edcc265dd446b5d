// Command-line flags shared by the simulator commands: which effects the simulated
// catheter has (--effects SPEC, where `@path/effect.json` adds an effect file), effect
// plugins (--plugin FILE.so), parameter overrides (--set effect.param=value) and the
// noise seed (--seed).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "apps/commands/effect_catalog_flags.h"

namespace CLI {
class App;
}

namespace echoservo::apps {

struct PlantFlags {
  std::string effects;  // model SPEC, empty: the command's default plant
  std::vector<std::string> sets;
  std::uint64_t seed = 1;
  CatalogFlags catalog;

  // Catalog names (validated; effect files read and registered in the catalog), or empty.
  // Builds the catalog (BuildCatalog) even when --effects is not given.
  std::vector<std::string> Effects() const;
  // The catalog the names refer to.
  const hw::EffectRegistry& Registry() const;
  std::vector<std::pair<std::string, double>> Parameters() const;
};

void AddPlantFlags(CLI::App* app, PlantFlags& flags);

}  // namespace echoservo::apps
