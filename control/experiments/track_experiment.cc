#include "control/experiments/track_experiment.h"

#include <cmath>
#include <memory>
#include <stdexcept>

#include "hw/seed_plant.h"

namespace echoservo::control {
namespace {

std::vector<double> TipErrors(const std::vector<CycleRecord>& records, double from_s) {
  std::vector<double> e;
  for (const CycleRecord& r : records) {
    if (r.t_s >= from_s) e.push_back(r.reference_mm - r.tip_mm);
  }
  return e;
}

std::vector<CycleRecord> RunOnce(const TrackOptions& o, const Trajectory& reference,
                                 BacklashCompensator& compensator, std::uint64_t* faults) {
  hw::SimulatedCatheter plant(o.plant);
  plant.ResetTo(reference.Evaluate(0.0).position_mm);  // start on the reference
  plant.Configure();
  plant.Activate();
  ServoLoop loop(plant, o.servo);
  std::vector<CycleRecord> records = RunFixedStep(loop, reference, compensator, o.duration_s);
  *faults += loop.limiter().faults();
  return records;
}

}  // namespace

void TrackOptions::Validate() const {
  MakeTrajectory(trajectory);  // throws naming the spec and the bad field
  if (compensation != "none" && compensation != "inverse" && compensation != "iterative" &&
      compensation != "adaptive") {
    throw std::invalid_argument(
        "track: --compensation must be none, inverse, iterative or adaptive, got '" + compensation +
        "'");
  }
  if (!(std::isfinite(duration_s) && duration_s > 0.0 && duration_s <= 600.0)) {
    throw std::invalid_argument("track: --duration must be in (0, 600] s");
  }
  if (!(std::isfinite(metrics_start_s) && metrics_start_s >= 0.0 && metrics_start_s < duration_s)) {
    throw std::invalid_argument("track: --metrics-start must be in [0, duration)");
  }
  if (iterations < 1 || iterations > 50)
    throw std::invalid_argument("track: --iterations must be in [1, 50]");
  servo.Validate();
}

ServoConfig SeedServoConfig(const hw::PlantOptions& plant, bool friction_feedforward) {
  ServoConfig c;
  c.limits.max_force_n = plant.actuator.PeakForceN();
  c.pid.output_limit_n = plant.actuator.PeakForceN();
  c.feedforward.moving_mass_kg = plant.actuator.moving_mass_kg;
  if (friction_feedforward) {
    // Nominal friction of the configuration, as calibration would measure it.
    hw::SimulatedCatheter probe(plant);
    c.feedforward.coulomb_n = probe.model().FrictionLevelN();
    c.feedforward.viscous_n_per_mm_s = probe.model().ViscousSlopeNPerMmS();
  }
  return c;
}

TrackOptions TrackOptions::SeedDefaults() {
  TrackOptions o;
  o.plant = hw::SeedCalibratedPlant(hw::SeedTrackingCatheter());
  o.servo = SeedServoConfig(o.plant, o.friction_feedforward);
  return o;
}

TrackResult RunTrackExperiment(const TrackOptions& o) {
  o.Validate();
  const std::unique_ptr<Trajectory> reference = MakeTrajectory(o.trajectory);
  TrackResult result;
  const double geometric_width = o.plant.config.TotalBendRad() * o.plant.config.GapMm();

  if (o.compensation == "iterative") {
    IterativeInverse ilc;
    for (int run = 0; run <= o.iterations; ++run) {
      result.records = RunOnce(o, *reference, ilc, &result.limit_faults);
      std::vector<double> all_errors;
      for (const CycleRecord& r : result.records) all_errors.push_back(r.reference_mm - r.tip_mm);
      result.per_run.push_back(ComputeErrorStats(TipErrors(result.records, o.metrics_start_s)));
      if (run < o.iterations) ilc.Learn(all_errors);
    }
  } else if (o.compensation == "adaptive") {
    AdaptiveOptions a;
    a.initial_width_mm = geometric_width;
    a.max_acceleration_mm_s2 = o.servo.limits.max_acceleration_mm_s2;
    AdaptiveInverse comp(a);
    result.records = RunOnce(o, *reference, comp, &result.limit_faults);
    result.width_estimate_mm = comp.width_mm();
    result.lag_estimate_s = comp.lag_s();
  } else if (o.compensation == "inverse") {
    StaticInverse comp(geometric_width, o.servo.limits.max_acceleration_mm_s2);
    result.records = RunOnce(o, *reference, comp, &result.limit_faults);
    result.width_estimate_mm = geometric_width;
  } else {
    NoCompensation comp;
    result.records = RunOnce(o, *reference, comp, &result.limit_faults);
  }
  result.tip = ComputeErrorStats(TipErrors(result.records, o.metrics_start_s));
  return result;
}

}  // namespace echoservo::control
