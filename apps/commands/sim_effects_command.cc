// `echoservo sim effects`: the catalog of catheter effects (hw/effects/) with their physics,
// parameters (units, defaults, bounds) and signature in data (docs/effects.md), plus the
// effects of --plugin FILE.so and --effect-file FILE.json (docs/effect_files.md).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "apps/commands/effect_catalog_flags.h"
#include "apps/commands/sim_command.h"
#include "hw/effect_file.h"
#include "hw/effect_registry.h"

namespace echoservo::apps {
namespace {

struct EffectsFlags {
  bool json = false;
  CatalogFlags catalog;
  std::vector<std::string> files;
};

void RunEffects(const EffectsFlags& f) {
  const bool json = f.json;
  hw::EffectRegistry& registry = BuildCatalog(f.catalog);
  std::string spec;
  for (const std::string& file : f.files) spec += (spec.empty() ? "@" : "+@") + file;
  if (!spec.empty()) hw::ResolveModelSpec(spec, registry);
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
                   {"source", registry.Source(name)},
                   {"in_seed_model", std::find(hw::SeedEffects().begin(), hw::SeedEffects().end(),
                                               name) != hw::SeedEffects().end()}});
  }
  if (json) {
    std::cout << nlohmann::json{{"effects", out}}.dump(2) << "\n";
    return;
  }
  for (const auto& e : out) {
    std::cout << e["name"].get<std::string>() << "  [" << e["stage"].get<std::string>() << "]"
              << (e["in_seed_model"].get<bool>() ? "  (seed)" : "")
              << (e["source"].get<std::string>().empty()
                      ? ""
                      : "  (@" + e["source"].get<std::string>() + ")")
              << "\n  " << e["description"].get<std::string>()
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
  auto flags = std::make_shared<EffectsFlags>();
  auto* cmd = sim->add_subcommand(
      "effects", "List the catalog of catheter effects with their physics and parameters");
  cmd->add_flag("--json", flags->json, "Print JSON");
  AddCatalogFlags(cmd, flags->catalog);
  cmd->add_option("--effect-file", flags->files,
                  "Also list the effect of FILE.json (repeatable; docs/effect_files.md)");
  cmd->callback([flags] { RunEffects(*flags); });
}

}  // namespace echoservo::apps
