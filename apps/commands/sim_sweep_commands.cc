// `echoservo sim friction` and `echoservo sim backlash`: the seed's bench sweeps.
#include <CLI/CLI.hpp>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "apps/commands/plant_flags.h"
#include "apps/commands/sim_command.h"
#include "apps/output.h"
#include "control/experiments/bench_experiments.h"
#include "control/experiments/track_experiment.h"
#include "formats/trial_io.h"
#include "hw/seed_plant.h"

namespace echoservo::apps {
namespace {

struct SweepFlags {
  PlantFlags plant;
  double tip_load_n = 0.0;
  bool tip_load_n_set = false;
  std::string catheter;
  bool json = false;
  control::SweepOptions Options() const {
    control::SweepOptions o;
    o.effects = plant.Effects();
    o.parameters = plant.Parameters();
    o.seed = plant.seed;
    o.tip_load_n = tip_load_n;
    return o;
  }
};

nlohmann::json ConfigJson(const formats::CatheterConfig& c) {
  return {{"sheath_id_mm", c.sheath_id_mm},
          {"guidewire_od_mm", c.guidewire_od_mm},
          {"gap_mm", c.GapMm()},
          {"bend_angle_deg", c.bends.front().angle_deg},
          {"bend_radius_mm", c.bends.front().radius_mm},
          {"tip_load_n", c.tip_load_n}};
}

void RunFriction(const SweepFlags& f) {
  const auto results = control::RunFrictionSweep(f.Options());
  nlohmann::json out = nlohmann::json::array();
  for (const auto& r : results) {
    nlohmann::json samples = nlohmann::json::array();
    for (const auto& s : r.samples)
      samples.push_back({{"velocity_mm_s", s.velocity_mm_s}, {"force_n", s.force_n}});
    out.push_back({{"config", ConfigJson(r.config)},
                   {"coulomb_n", r.fit.coulomb_n},
                   {"coulomb_sd_n", r.fit.coulomb_sd_n},
                   {"viscous_n_per_mm_s", r.fit.viscous_n_per_mm_s},
                   {"viscous_sd_n_per_mm_s", r.fit.viscous_sd_n_per_mm_s},
                   {"fit_rms_n", r.fit.rms_n},
                   {"fit_r2", r.fit.r2},
                   {"samples", samples}});
  }
  if (f.json) {
    std::cout << nlohmann::json{{"configs", out}}.dump(2) << "\n";
    return;
  }
  std::cout
      << "Friction vs velocity, constant-velocity strokes in both directions; fit F = Fc*sign(v) + "
         "b*v\n"
         "(seed: ~1.0 N Coulomb + 0.006 N/(mm/s) viscous; bend angle matters, radius does not)\n\n";
  Table t({"sheath_id", "gw_od", "gap", "bend_deg", "radius", "Fc_N", "sd", "b_N/(mm/s)", "sd",
           "rms_N"});
  for (const auto& r : results) {
    t.AddRow({Fixed(r.config.sheath_id_mm, 2), Fixed(r.config.guidewire_od_mm, 2),
              Fixed(r.config.GapMm(), 2), Fixed(r.config.bends.front().angle_deg, 0),
              Fixed(r.config.bends.front().radius_mm, 0), Fixed(r.fit.coulomb_n, 3),
              Fixed(r.fit.coulomb_sd_n, 3), Fixed(r.fit.viscous_n_per_mm_s, 4),
              Fixed(r.fit.viscous_sd_n_per_mm_s, 4), Fixed(r.fit.rms_n, 3)});
  }
  t.Print(std::cout);
}

void RunBacklash(const SweepFlags& f) {
  const control::BacklashSweepResult r = control::RunBacklashSweep(f.Options());
  nlohmann::json configs = nlohmann::json::array();
  for (const auto& c : r.configs) {
    configs.push_back({{"config", ConfigJson(c.config)},
                       {"measured_width_mm", c.measured_width_mm},
                       {"model_width_mm", c.model_width_mm}});
  }
  if (f.json) {
    std::cout << nlohmann::json{{"configs", configs},
                                {"model", "B = theta * (D_sheath - D_guidewire)"},
                                {"model_rms_error_mm", r.rms_error_mm},
                                {"model_r2", r.r2},
                                {"seed_published", {{"rms_error_mm", 0.4}, {"r2", 0.93}}}}
                     .dump(2)
              << "\n";
    return;
  }
  std::cout << "Backlash: hysteresis width of tip vs base on a 5 mm, 1 Hz sine, against B = "
               "theta*gap\n\n";
  Table t({"sheath_id", "gw_od", "gap", "bend_deg", "radius", "measured_mm", "theta*gap_mm",
           "error_mm"});
  for (const auto& c : r.configs) {
    t.AddRow({Fixed(c.config.sheath_id_mm, 2), Fixed(c.config.guidewire_od_mm, 2),
              Fixed(c.config.GapMm(), 2), Fixed(c.config.bends.front().angle_deg, 0),
              Fixed(c.config.bends.front().radius_mm, 0), Fixed(c.measured_width_mm, 3),
              Fixed(c.model_width_mm, 3), Fixed(c.model_width_mm - c.measured_width_mm, 3)});
  }
  t.Print(std::cout);
  std::cout << "\nmodel B = theta*gap: RMS error " << Fixed(r.rms_error_mm, 3) << " mm, r^2 "
            << Fixed(r.r2, 3) << "   (seed, measured: RMS 0.4 mm, r^2 0.93)\n";
}

void RunCalibrate(const SweepFlags& f) {
  control::SweepOptions o = f.Options();
  formats::CatheterConfig config =
      f.catheter.empty() ? hw::SeedTrackingCatheter() : formats::ReadCatheterConfig(f.catheter);
  if (f.tip_load_n_set) config.tip_load_n = f.tip_load_n;
  hw::SimulatedCatheter plant(control::SweepPlant(o, config, false));
  plant.Configure();
  plant.Activate();
  const control::CalibrationResult r =
      control::Calibrate(plant, control::SeedServoConfig(plant.options(), false), o.probe);
  // What the simulator knows (a real rig would not): the friction level and the width
  // of the tip-vs-base loop it should produce (deadzone plus 2F/k with compliance).
  const double truth_friction = plant.model().FrictionLevelN();
  const double truth_viscous = plant.model().ViscousSlopeNPerMmS();
  const double truth_width = plant.model().BacklashWidthMm();
  if (f.json) {
    nlohmann::json samples = nlohmann::json::array();
    for (const auto& s : r.friction_samples)
      samples.push_back({{"velocity_mm_s", s.velocity_mm_s}, {"force_n", s.force_n}});
    std::cout << nlohmann::json{{"config", ConfigJson(config)},
                                {"coulomb_n", r.friction.coulomb_n},
                                {"coulomb_sd_n", r.friction.coulomb_sd_n},
                                {"viscous_n_per_mm_s", r.friction.viscous_n_per_mm_s},
                                {"viscous_sd_n_per_mm_s", r.friction.viscous_sd_n_per_mm_s},
                                {"backlash_width_mm", r.backlash.width_mm},
                                {"samples", samples},
                                {"truth",
                                 {{"friction_level_n", truth_friction},
                                  {"viscous_n_per_mm_s", truth_viscous},
                                  {"deadzone_width_mm", truth_width}}}}
                     .dump(2)
              << "\n";
    return;
  }
  std::cout << "Calibration by probing motions on the seed's tracking catheter (simulated)\n\n";
  Table t({"quantity", "estimate", "sd", "simulator truth"});
  t.AddRow({"Coulomb friction (N)", Fixed(r.friction.coulomb_n, 3),
            Fixed(r.friction.coulomb_sd_n, 3), Fixed(truth_friction, 3)});
  t.AddRow({"viscous (N/(mm/s))", Fixed(r.friction.viscous_n_per_mm_s, 4),
            Fixed(r.friction.viscous_sd_n_per_mm_s, 4), Fixed(truth_viscous, 4)});
  t.AddRow({"hysteresis width (mm)", Fixed(r.backlash.width_mm, 3), "-",
            Fixed(truth_width, 3) + " (deadzone)"});
  t.Print(std::cout);
}

CLI::App* AddSweep(CLI::App* sim, const char* name, const char* help,
                   void (*run)(const SweepFlags&), std::shared_ptr<SweepFlags> flags = nullptr) {
  if (!flags) flags = std::make_shared<SweepFlags>();
  auto* cmd = sim->add_subcommand(name, help);
  cmd->add_option("--tip-load", flags->tip_load_n, "Normal force at the tip (N)")
      ->each([flags](const std::string&) { flags->tip_load_n_set = true; });
  cmd->add_flag("--json", flags->json, "Print JSON");
  AddPlantFlags(cmd, flags->plant);
  cmd->callback([flags, run] { run(*flags); });
  return cmd;
}

}  // namespace

void AddSimSweeps(CLI::App* sim) {
  AddSweep(sim, "friction",
           "Friction vs velocity for every Table I geometry x bend angle x radius; fitted Coulomb "
           "and viscous terms",
           RunFriction);
  AddSweep(sim, "backlash",
           "Hysteresis width on a 5 mm, 1 Hz sine for every configuration against B = theta*gap "
           "(RMS error, r^2)",
           RunBacklash);
  auto flags = std::make_shared<SweepFlags>();
  auto* calibrate = AddSweep(sim, "calibrate",
                             "Estimate friction and backlash width from short probing motions (the "
                             "seed's calibration), by default on the seed's tracking catheter",
                             RunCalibrate, flags);
  calibrate->add_option(
      "--catheter", flags->catheter,
      "Catheter geometry JSON (sheath_id_mm, guidewire_od_mm, bends, tip_load_n)");
}

}  // namespace echoservo::apps
