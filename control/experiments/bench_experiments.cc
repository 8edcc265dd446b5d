#include "control/experiments/bench_experiments.h"

#include <algorithm>
#include <cmath>

#include "control/experiments/track_experiment.h"
#include "hw/seed_plant.h"

namespace echoservo::control {
namespace {

struct ActivePlant {
  explicit ActivePlant(const hw::PlantOptions& o) : plant(o) {
    plant.Configure();
    plant.Activate();
  }
  hw::SimulatedCatheter plant;
};

}  // namespace

hw::PlantOptions SweepPlant(const SweepOptions& options, const formats::CatheterConfig& config,
                            bool seed_model_default) {
  hw::PlantOptions o = seed_model_default ? hw::SeedModelPlant(config, options.seed)
                                          : hw::SeedCalibratedPlant(config, options.seed);
  hw::SelectEffects(o, options.effects, options.parameters);
  return o;
}

std::vector<FrictionConfigResult> RunFrictionSweep(const SweepOptions& options) {
  options.probe.Validate();
  std::vector<FrictionConfigResult> results;
  for (const formats::CatheterConfig& config : hw::TableOneSweep(options.tip_load_n)) {
    ActivePlant p(SweepPlant(options, config, false));
    const ServoConfig servo = SeedServoConfig(p.plant.options(), false);
    FrictionConfigResult r;
    r.config = config;
    r.samples = ProbeFriction(p.plant, servo, options.probe);
    r.fit = FitCoulombViscous(r.samples);
    results.push_back(std::move(r));
  }
  return results;
}

BacklashSweepResult RunBacklashSweep(const SweepOptions& options) {
  options.probe.Validate();
  BacklashSweepResult result;
  double mean = 0.0;
  for (const formats::CatheterConfig& config : hw::TableOneSweep(options.tip_load_n)) {
    ActivePlant p(SweepPlant(options, config, true));
    const ServoConfig servo = SeedServoConfig(p.plant.options(), false);
    BacklashConfigResult r;
    r.config = config;
    r.measured_width_mm = ProbeBacklash(p.plant, servo, options.probe).width_mm;
    r.model_width_mm = config.TotalBendRad() * config.GapMm();
    mean += r.measured_width_mm;
    result.configs.push_back(r);
  }
  const auto n = static_cast<double>(result.configs.size());
  mean /= n;
  double ss_res = 0.0;
  double ss_tot = 0.0;
  for (const BacklashConfigResult& r : result.configs) {
    ss_res += std::pow(r.measured_width_mm - r.model_width_mm, 2);
    ss_tot += std::pow(r.measured_width_mm - mean, 2);
  }
  result.rms_error_mm = std::sqrt(ss_res / n);
  result.r2 = ss_tot > 0.0 ? 1.0 - ss_res / ss_tot : 0.0;
  return result;
}

}  // namespace echoservo::control
