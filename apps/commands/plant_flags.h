// Command-line flags shared by the simulator commands: which effects the simulated
// catheter has (--effects SPEC), parameter overrides (--set effect.param=value) and
// the noise seed (--seed).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace CLI {
class App;
}

namespace echoservo::apps {

struct PlantFlags {
  std::string effects;  // model SPEC, empty: the command's default plant
  std::vector<std::string> sets;
  std::uint64_t seed = 1;

  // Catalog names (validated), or empty.
  std::vector<std::string> Effects() const;
  std::vector<std::pair<std::string, double>> Parameters() const;
};

void AddPlantFlags(CLI::App* app, PlantFlags& flags);

}  // namespace echoservo::apps
