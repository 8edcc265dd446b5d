// `echoservo sim track`: the seed's tip-tracking experiment.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "apps/commands/plant_flags.h"
#include "apps/commands/sim_command.h"
#include "apps/output.h"
#include "control/experiments/track_experiment.h"
#include "formats/trial_io.h"
#include "hw/seed_plant.h"

namespace echoservo::apps {
namespace {

struct TrackFlags {
  std::string trajectory = "sine";
  std::string compensation = "none";
  double duration_s = 12.0;
  double metrics_start_s = 2.0;
  int iterations = 1;
  std::string record_dir;
  std::string catheter;
  bool json = false;
  PlantFlags plant;
};

// The seed's published tip MAE (Kesner & Howe 2010), mm; < 0 where none was published.
// Only the default trajectories are the seed's.
double SeedMae(const std::string& trajectory, const std::string& compensation) {
  if (trajectory != "sine" && trajectory != "mitral") return -1.0;
  if (compensation == "none") return trajectory == "sine" ? 1.28 : 1.19;
  if (compensation == "iterative") return trajectory == "sine" ? 0.26 : 0.24;
  return -1.0;
}

nlohmann::json RunOne(const TrackFlags& f, const std::string& trajectory,
                      const std::string& compensation) {
  control::TrackOptions o = control::TrackOptions::SeedDefaults();
  if (!f.catheter.empty()) o.plant.config = formats::ReadCatheterConfig(f.catheter);
  o.trajectory = trajectory;
  o.compensation = compensation;
  o.duration_s = f.duration_s;
  o.metrics_start_s = f.metrics_start_s;
  o.iterations = f.iterations;
  hw::SelectEffects(o.plant, f.plant.Effects(), f.plant.Parameters());
  o.plant.registry = &f.plant.Registry();
  o.plant.seed = f.plant.seed;
  o.servo = control::SeedServoConfig(o.plant, o.friction_feedforward);
  const control::TrackResult r = control::RunTrackExperiment(o);

  nlohmann::json j = {{"trajectory", trajectory},
                      {"compensation", compensation},
                      {"mae_mm", r.tip.mae_mm},
                      {"rms_mm", r.tip.rms_mm},
                      {"max_mm", r.tip.max_abs_mm},
                      {"samples", r.tip.samples},
                      {"metrics_window_s", {f.metrics_start_s, f.duration_s}},
                      {"limit_faults", r.limit_faults}};
  if (compensation == "inverse" || compensation == "adaptive")
    j["width_estimate_mm"] = r.width_estimate_mm;
  if (compensation == "adaptive") j["lag_estimate_s"] = r.lag_estimate_s;
  if (!r.per_run.empty()) {
    nlohmann::json runs = nlohmann::json::array();
    for (std::size_t i = 0; i < r.per_run.size(); ++i) {
      runs.push_back(
          {{"run", i}, {"mae_mm", r.per_run[i].mae_mm}, {"rms_mm", r.per_run[i].rms_mm}});
    }
    j["runs"] = runs;
  }
  const double seed = SeedMae(trajectory, compensation);
  if (seed > 0) {
    j["seed_published_mae_mm"] = seed;
    j["ratio_to_seed"] = r.tip.mae_mm / seed;
  } else {
    j["seed_published_mae_mm"] = nullptr;
  }
  if (!f.record_dir.empty()) {
    formats::Trial trial;
    trial.name = "track_" + trajectory + "_" + compensation;
    for (char& c : trial.name) {
      if (c == ':') c = '_';
    }
    trial.config = o.plant.config;
    for (const control::CycleRecord& c : r.records) {
      trial.t_s.push_back(c.t_s);
      trial.base_cmd_mm.push_back(c.base_cmd_mm);
      trial.base_mm.push_back(c.base_mm);
      trial.tip_mm.push_back(c.tip_mm);
      trial.force_n.push_back(c.force_n);
    }
    trial.extra_names = {"reference"};
    trial.extra_columns.emplace_back();
    for (const control::CycleRecord& c : r.records)
      trial.extra_columns[0].push_back(c.reference_mm);
    formats::WriteTrial(f.record_dir, trial);
    j["recorded"] = (std::filesystem::path(f.record_dir) / (trial.name + ".csv")).string();
  }
  return j;
}

void Run(const TrackFlags& f) {
  const std::vector<std::string> trajectories = f.trajectory == "all"
                                                    ? std::vector<std::string>{"sine", "mitral"}
                                                    : SplitList(f.trajectory, "--trajectory");
  const std::vector<std::string> compensations =
      f.compensation == "all" ? std::vector<std::string>{"none", "inverse", "iterative", "adaptive"}
                              : SplitList(f.compensation, "--compensation");
  nlohmann::json results = nlohmann::json::array();
  for (const std::string& t : trajectories) {
    for (const std::string& c : compensations) results.push_back(RunOne(f, t, c));
  }
  if (f.json) {
    std::cout << (results.size() == 1 ? results[0] : nlohmann::json{{"results", results}}).dump(2)
              << "\n";
    return;
  }
  std::cout << (f.catheter.empty()
                    ? "Tip tracking on the seed-calibrated catheter (0.8 mm guidewire in a 1.6 mm "
                      "sheath,\n"
                      "two 90 deg bends, tip seal)"
                    : "Tip tracking on the seed-calibrated plant with the catheter of " +
                          f.catheter)
            << "; error = reference - measured tip over t in [" << f.metrics_start_s << ", "
            << f.duration_s << "] s\n\n";
  Table table({"trajectory", "compensation", "mae_mm", "rms_mm", "max_mm", "seed_mae_mm", "ratio"});
  for (const auto& j : results) {
    const bool has_seed = !j["seed_published_mae_mm"].is_null();
    auto num = [&](const char* key, int decimals) { return Fixed(j[key].get<double>(), decimals); };
    table.AddRow({j["trajectory"].get<std::string>(), j["compensation"].get<std::string>(),
                  num("mae_mm", 3), num("rms_mm", 3), num("max_mm", 3),
                  has_seed ? num("seed_published_mae_mm", 2) : "-",
                  has_seed ? num("ratio_to_seed", 2) : "-"});
  }
  table.Print(std::cout);
  for (const auto& j : results) {
    if (j.contains("runs")) {
      std::cout << "\n"
                << j["trajectory"].get<std::string>()
                << " iterative, MAE per run (run 0 uncompensated):";
      for (const auto& r : j["runs"]) std::cout << " " << Fixed(r["mae_mm"].get<double>(), 3);
      std::cout << "\n";
    }
    if (j.contains("recorded"))
      std::cout << "recorded " << j["recorded"].get<std::string>() << "\n";
  }
}

}  // namespace

void AddSimTrack(CLI::App* sim) {
  auto flags = std::make_shared<TrackFlags>();
  auto* cmd =
      sim->add_subcommand("track", "The seed's tip-tracking experiment: tip MAE/RMS/max (mm)");
  cmd->add_option("--trajectory", flags->trajectory,
                  "sine | mitral | all, or a spec such as sine:5:1, mitral:72:14 (comma-separated "
                  "list allowed)");
  cmd->add_option("--compensation", flags->compensation,
                  "none | inverse | iterative | adaptive | all");
  cmd->add_option("--duration", flags->duration_s, "Run length (s)");
  cmd->add_option("--metrics-start", flags->metrics_start_s, "Start of the metrics window (s)");
  cmd->add_option("--iterations", flags->iterations,
                  "Iterative: learning runs before the reported one (the seed's procedure: 1)");
  cmd->add_option("--catheter", flags->catheter,
                  "Catheter geometry JSON (sheath_id_mm, guidewire_od_mm, bends, tip_load_n); "
                  "default: the seed's tracking catheter");
  cmd->add_option("--record", flags->record_dir,
                  "Write the reported run(s) as trials into this folder");
  cmd->add_flag("--json", flags->json, "Print JSON");
  AddPlantFlags(cmd, flags->plant);
  cmd->callback([flags] { Run(*flags); });
}

}  // namespace echoservo::apps
