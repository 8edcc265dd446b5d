// `echoservo sim effects`: the catalog of catheter effects (hw/effects/) with their physics,
// parameters (units, defaults, bounds) and signature in data (docs/effects.md).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "apps/commands/sim_command.h"
#include "hw/effect_registry.h"

namespace echoservo::apps {
namespace {

void RunEffects(bool json) {
  const hw::EffectRegistry registry = hw::EffectRegistry::WithBuiltinEffects();
  nlohmann::json out = nlohmann::json::array();
  for (const std::string& name : registry.Names()) {
    const auto effect = registry.Create(name);
    nlohmann::json params = nlohmann::json::array();
    for (const hw::ParameterSpec& p : effect->parameters()) {
      params.push_back({{"name", p.name},
                        {"unit", p.unit},
                        {"default", p.default_value},
                        {"lower", p.lower},
                        {"upper", p.upper},
                        {"doc", p.doc}});
    }
    out.push_back({{"name", name},
                   {"stage", std::string(hw::ToString(effect->stage()))},
                   {"description", std::string(effect->description())},
                   {"signature", std::string(effect->signature())},
                   {"parameters", params},
                   {"in_seed_model", std::find(hw::SeedEffects().begin(), hw::SeedEffects().end(),
                                               name) != hw::SeedEffects().end()}});
  }
  if (json) {
    std::cout << nlohmann::json{{"effects", out}}.dump(2) << "\n";
    return;
  }
  for (const auto& e : out) {
    std::cout << e["name"].get<std::string>() << "  [" << e["stage"].get<std::string>() << "]"
              << (e["in_seed_model"].get<bool>() ? "  (seed)" : "") << "\n  "
              << e["description"].get<std::string>()
              << "\n  in data: " << e["signature"].get<std::string>() << "\n";
    for (const auto& p : e["parameters"]) {
      std::cout << "    " << p["name"].get<std::string>() << " [" << p["unit"].get<std::string>()
                << "] default " << p["default"].get<double>() << ", bounds ["
                << p["lower"].get<double>() << ", " << p["upper"].get<double>()
                << "]: " << p["doc"].get<std::string>() << "\n";
    }
    std::cout << "\n";
  }
}

}  // namespace

void AddSimEffects(CLI::App* sim) {
  auto json = std::make_shared<bool>(false);
  auto* cmd = sim->add_subcommand(
      "effects", "List the catalog of catheter effects with their physics and parameters");
  cmd->add_flag("--json", *json, "Print JSON");
  cmd->callback([json] { RunEffects(*json); });
}

}  // namespace echoservo::apps
