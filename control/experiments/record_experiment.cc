#include "control/experiments/record_experiment.h"

#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "control/backlash_compensation.h"
#include "control/experiments/bench_experiments.h"
#include "control/experiments/track_experiment.h"
#include "formats/trial_io.h"
#include "hw/effect_registry.h"
#include "hw/seed_plant.h"

namespace echoservo::control {
namespace {

std::string TrialName(std::size_t index, const formats::CatheterConfig& c,
                      const std::string& trajectory) {
  std::string traj = trajectory;
  for (char& ch : traj) {
    if (ch == ':') ch = '_';
  }
  char buf[160];
  std::snprintf(buf, sizeof buf, "trial_%03zu_id%.2f_od%.2f_bend%.0f_r%.0f_load%.2f_%s", index,
                c.sheath_id_mm, c.guidewire_od_mm, c.TotalBendRad() * 180.0 / 3.141592653589793,
                c.bends.empty() ? 0.0 : c.bends.front().radius_mm, c.tip_load_n, traj.c_str());
  return buf;
}

std::string MetaJson(const hw::PlantOptions& plant, const std::string& trajectory,
                     const std::string& compensation) {
  // Parameter values are numbers; names come from the catalog (no quoting needed).
  std::string params;
  const hw::SimulatedCatheter probe(plant);
  for (const hw::ParameterInfo& p : probe.model().parameter_info()) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s\"%s\": %.17g", params.empty() ? "" : ", ",
                  p.qualified_name.c_str(), probe.model().GetParameter(p.qualified_name));
    params += buf;
  }
  return "{\"generator\": \"echoservo sim record\", \"trajectory\": \"" + trajectory +
         "\", \"compensation\": \"" + compensation + "\", \"truth_effects\": \"" +
         hw::FormatModelSpec(plant.effects) + "\", \"truth_parameters\": {" + params +
         "}, \"seed\": " + std::to_string(plant.seed) + "}";
}

}  // namespace

void RecordOptions::Validate() const {
  if (out_dir.empty()) throw std::invalid_argument("record: --out is required");
  if (configs != "table1" && configs != "seed" && configs != "lab") {
    throw std::invalid_argument("record: --configs must be table1, seed or lab, got '" + configs +
                                "'");
  }
  if (trajectories.empty()) throw std::invalid_argument("record: --trajectories is empty");
  for (const std::string& t : trajectories) MakeTrajectory(t);  // throws naming the spec
  if (tip_loads_n.empty()) throw std::invalid_argument("record: --tip-loads is empty");
  for (double l : tip_loads_n) {
    if (!(std::isfinite(l) && l >= 0.0 && l <= 50.0)) {
      throw std::invalid_argument("record: --tip-loads values must be in [0, 50] N");
    }
  }
  if (compensation != "none" && compensation != "inverse" && compensation != "adaptive") {
    throw std::invalid_argument("record: --compensation must be none, inverse or adaptive");
  }
  if (!(std::isfinite(duration_s) && duration_s >= 0.5 && duration_s <= 600.0)) {
    throw std::invalid_argument("record: --duration must be in [0.5, 600] s");
  }
}

std::vector<formats::CatheterConfig> RecordConfigs(const std::string& name, double tip_load_n) {
  if (name == "lab") {
    // Eight catheters that vary gap, total bend angle and tip load independently, so
    // that effects scaling with each can be told apart (the tip load given is added).
    struct Row {
      double id, od, bend_deg, load;
    };
    const Row rows[] = {{1.59, 0.76, 180, 0.0}, {1.59, 0.76, 360, 1.5}, {2.38, 2.23, 180, 1.5},
                        {2.38, 2.23, 360, 0.0}, {2.38, 1.50, 90, 0.5},  {2.38, 1.50, 270, 2.0},
                        {1.59, 1.50, 360, 1.0}, {1.59, 0.76, 90, 3.0}};
    std::vector<formats::CatheterConfig> out;
    for (const Row& r : rows) {
      formats::CatheterConfig c;
      c.sheath_id_mm = r.id;
      c.guidewire_od_mm = r.od;
      c.bends = {{0.5 * r.bend_deg, 50.0}, {0.5 * r.bend_deg, 25.0}};
      c.tip_load_n = r.load + tip_load_n;
      out.push_back(c);
    }
    return out;
  }
  if (name == "seed") {
    formats::CatheterConfig c = formats::CatheterConfig::SeedEvaluation();
    c.tip_load_n = tip_load_n;
    return {c};
  }
  return hw::TableOneSweep(tip_load_n);
}

RecordResult RecordDataset(const RecordOptions& o) {
  o.Validate();
  RecordResult result;
  SweepOptions sweep;
  sweep.effects = o.effects;
  sweep.parameters = o.parameters;
  sweep.seed = o.seed;
  std::size_t index = 0;
  for (double load : o.tip_loads_n) {
    for (const formats::CatheterConfig& config : RecordConfigs(o.configs, load)) {
      for (const std::string& spec : o.trajectories) {
        hw::PlantOptions plant_options = SweepPlant(sweep, config, false);
        plant_options.seed = o.seed + index;
        const std::unique_ptr<Trajectory> reference = MakeTrajectory(spec);
        hw::SimulatedCatheter plant(plant_options);
        plant.ResetTo(reference->Evaluate(0.0).position_mm);
        plant.Configure();
        plant.Activate();
        const ServoConfig servo = SeedServoConfig(plant_options, true);
        const double width = config.TotalBendRad() * config.GapMm();
        std::unique_ptr<BacklashCompensator> comp;
        if (o.compensation == "inverse") {
          comp = std::make_unique<StaticInverse>(width, servo.limits.max_acceleration_mm_s2);
        } else if (o.compensation == "adaptive") {
          AdaptiveOptions a;
          a.initial_width_mm = width;
          a.max_acceleration_mm_s2 = servo.limits.max_acceleration_mm_s2;
          comp = std::make_unique<AdaptiveInverse>(a);
        } else {
          comp = std::make_unique<NoCompensation>();
        }
        ServoLoop loop(plant, servo);
        const std::vector<CycleRecord> records =
            RunFixedStep(loop, *reference, *comp, o.duration_s);

        formats::Trial trial;
        trial.name = TrialName(index, config, spec);
        trial.config = config;
        for (const CycleRecord& r : records) {
          trial.t_s.push_back(r.t_s);
          trial.base_cmd_mm.push_back(r.base_cmd_mm);
          trial.base_mm.push_back(r.base_mm);
          trial.tip_mm.push_back(r.tip_mm);
          trial.force_n.push_back(r.force_n);
        }
        trial.meta_json = MetaJson(plant_options, spec, o.compensation);
        formats::WriteTrial(o.out_dir, trial);
        result.trials.push_back(trial.name);
        result.samples += trial.size();
        ++index;
      }
    }
  }
  return result;
}

}  // namespace echoservo::control
