// `echoservo sim record`: runs chosen configurations, trajectories, tip loads and effects on
// the simulated catheter and writes a dataset in the trial format (docs/trial_format.md).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "apps/commands/plant_flags.h"
#include "apps/commands/sim_command.h"
#include "apps/output.h"
#include "control/experiments/record_experiment.h"
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

}  // namespace

void AddSimRecord(CLI::App* sim) {
  auto flags = std::make_shared<RecordFlags>();
  auto* cmd = sim->add_subcommand(
      "record",
      "Run chosen configurations/trajectories/effects and write a dataset in the trial format");
  cmd->add_option("--out", flags->out, "Output folder (created)")->required();
  cmd->add_option("--configs", flags->configs,
                  "table1 (24 Table I configurations) | seed (the tracking catheter) | lab (8 "
                  "catheters varying gap, bend angle, tip load)");
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

}  // namespace echoservo::apps
