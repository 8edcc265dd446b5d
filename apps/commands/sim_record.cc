// `echoservo sim record` (datasets in the trial format) and `echoservo sim effects`
// (the effect catalog).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "apps/commands/plant_flags.h"
#include "apps/commands/sim_commands.h"
#include "apps/output.h"
#include "control/record_experiment.h"
#include "hw/effect_registry.h"

namespace echoservo::apps {
namespace {

struct RecordFlags {
  std::string out;
  std::string configs = "table1";
  std::string trajectories = "sine";
  std::string tip_loads = "0";
  std::string compensation = "none";
  double duration_s = 6.0;
  bool json = false;
  PlantFlags plant;
};

void RunRecord(const RecordFlags& f) {
  control::RecordOptions o;
  o.out_dir = f.out;
  o.effects = f.plant.Effects();
  o.parameters = f.plant.Parameters();
  o.seed = f.plant.seed;
  o.configs = f.configs;
  o.trajectories = SplitList(f.trajectories, "--trajectories");
  o.tip_loads_n = ParseNumberList(f.tip_loads, "--tip-loads");
  o.compensation = f.compensation;
  o.duration_s = f.duration_s;
  const control::RecordResult r = control::RecordDataset(o);
  if (f.json) {
    std::cout << nlohmann::json{{"out", f.out}, {"trials", r.trials}, {"samples", r.samples}}.dump(
                     2)
              << "\n";
  } else {
    std::cout << "wrote " << r.trials.size() << " trials (" << r.samples << " samples) to " << f.out
              << "\n";
  }
}

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

void AddSimRecord(CLI::App* sim) {
  auto flags = std::make_shared<RecordFlags>();
  auto* cmd = sim->add_subcommand(
      "record",
      "Run chosen configurations/trajectories/effects and write a dataset in the trial format");
  cmd->add_option("--out", flags->out, "Output folder (created)")->required();
  cmd->add_option("--configs", flags->configs,
                  "table1 (24 Table I configurations) | seed (the tracking catheter) | lab (8 catheters varying gap, bend angle, tip load)");
  cmd->add_option(
      "--trajectories", flags->trajectories,
      "Comma-separated trajectory specs: sine, sine:A:F, triangle:A:V, mitral, mitral:BPM:P2P");
  cmd->add_option("--tip-loads", flags->tip_loads, "Comma-separated tip loads (N)");
  cmd->add_option("--compensation", flags->compensation, "none | inverse | adaptive");
  cmd->add_option("--duration", flags->duration_s, "Length of each trial (s)");
  cmd->add_flag("--json", flags->json, "Print JSON");
  AddPlantFlags(cmd, flags->plant);
  cmd->callback([flags] { RunRecord(*flags); });
}

void AddSimEffects(CLI::App* sim) {
  auto json = std::make_shared<bool>(false);
  auto* cmd = sim->add_subcommand(
      "effects", "List the catalog of catheter effects with their physics and parameters");
  cmd->add_flag("--json", *json, "Print JSON");
  cmd->callback([json] { RunEffects(*json); });
}

}  // namespace echoservo::apps
