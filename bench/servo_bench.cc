// echoservo benchmarks: how fast the simulated 1 kHz servo runs against the wall clock.
//
//  - BM_SimulatedServoRealtimeFactor: the seed-calibrated SimulatedCatheter (default
//    10 physics substeps per 1 ms cycle) under the seed ServoLoop with AdaptiveInverse
//    compensation on the 5 mm, 1 Hz sine. One iteration = 1 s of simulated time
//    (1000 servo cycles). Counters: realtime_factor (simulated s per wall s) and
//    cycles_per_s (servo cycles per wall s). Target: realtime_factor >= 1000 on one core.
//  - BM_SimulatedServoReferenceIntegrator: the same loop with the plant at 50 substeps
//    (a conservative explicit-integration step, h = 20 us) as the same-process baseline,
//    so the cost of the default 10-substep plant can be read as a ratio.
//  - BM_PlantWriteOnly: the plant alone, read()/write() at 1 kHz with a constant force
//    command (no controller, no compensator); same counters.
//  - BM_TransmissionModelFriction: one TransmissionModel::FrictionMagnitudeN call (the
//    per-substep friction evaluation of a sliding plant).
// All benchmarks measure wall time (UseRealTime), single-threaded. Standard Google
// Benchmark flags apply (--benchmark_filter, --benchmark_min_time, --benchmark_repetitions,
// --benchmark_counters_tabular, --benchmark_format=json, ...).
#include <benchmark/benchmark.h>

#include <cstddef>
#include <memory>
#include <string>

#include "control/backlash_compensation.h"
#include "control/experiments/track_experiment.h"
#include "control/servo_loop.h"
#include "control/trajectory.h"
#include "hw/seed_plant.h"
#include "hw/simulated_catheter.h"

namespace {

using echoservo::control::AdaptiveInverse;
using echoservo::control::AdaptiveOptions;
using echoservo::control::CycleRecord;
using echoservo::control::ServoConfig;
using echoservo::control::ServoLoop;
using echoservo::control::Trajectory;
using echoservo::hw::PlantOptions;
using echoservo::hw::SimulatedCatheter;

constexpr std::size_t kCyclesPerIteration = 1000;  // 1 s of simulated time at 1 kHz
constexpr std::size_t kRunIterations = 12;         // servo runs restart every 12 s

PlantOptions SeedPlant(int substeps) {
  PlantOptions o = echoservo::hw::SeedCalibratedPlant(echoservo::hw::SeedTrackingCatheter());
  o.substeps = substeps;
  return o;
}

void SetRateCounters(benchmark::State& state, double simulated_s, double cycles) {
  // kIsRate divides by the benchmark's measured time, which is wall time (UseRealTime).
  state.counters["realtime_factor"] = benchmark::Counter(simulated_s, benchmark::Counter::kIsRate);
  state.counters["cycles_per_s"] = benchmark::Counter(cycles, benchmark::Counter::kIsRate);
}

// The closed loop of the seed's tracking experiment as RunTrackExperiment builds it for
// --compensation adaptive. Iterations continue one run; every kRunIterations (12 s, the
// track experiment's default duration) the run restarts from t = 0 with the plant,
// loop and compensator reset, outside the timed region, so the timing stays that of
// the seed experiment's operating point however many iterations the benchmark picks.
void RunSimulatedServo(benchmark::State& state, int substeps) {
  const PlantOptions plant_options = SeedPlant(substeps);
  const ServoConfig servo = echoservo::control::SeedServoConfig(plant_options, true);
  const std::unique_ptr<Trajectory> reference = echoservo::control::MakeTrajectory("sine");

  SimulatedCatheter plant(plant_options);
  plant.ResetTo(reference->Evaluate(0.0).position_mm);
  plant.Configure();
  plant.Activate();
  ServoLoop loop(plant, servo);

  AdaptiveOptions adaptive;
  adaptive.initial_width_mm = plant_options.config.TotalBendRad() * plant_options.config.GapMm();
  adaptive.max_acceleration_mm_s2 = servo.limits.max_acceleration_mm_s2;
  AdaptiveInverse compensator(adaptive);
  const double start_mm = reference->Evaluate(0.0).position_mm;
  compensator.Reset();
  loop.Start(0.0);

  const double dt = servo.period_s;
  std::size_t k = 0;
  std::size_t iteration = 0;
  for (auto _ : state) {
    if (iteration++ == kRunIterations) {
      state.PauseTiming();
      plant.ResetTo(start_mm);
      compensator.Reset();
      loop.Start(0.0);
      k = 0;
      iteration = 1;
      state.ResumeTiming();
    }
    for (std::size_t i = 0; i < kCyclesPerIteration; ++i, ++k) {
      CycleRecord r = loop.Cycle(static_cast<double>(k) * dt, k, *reference, compensator);
      benchmark::DoNotOptimize(r);
    }
  }
  const auto iterations = static_cast<double>(state.iterations());
  SetRateCounters(state, iterations * static_cast<double>(kCyclesPerIteration) * dt,
                  iterations * static_cast<double>(kCyclesPerIteration));
  state.counters["substeps"] = substeps;
  state.counters["limit_faults"] = static_cast<double>(loop.limiter().faults());
  state.counters["width_est_mm"] = compensator.width_mm();  // of the last run, at its end
}

void BM_SimulatedServoRealtimeFactor(benchmark::State& state) {
  RunSimulatedServo(state, PlantOptions{}.substeps);  // the plant's default (10)
}
BENCHMARK(BM_SimulatedServoRealtimeFactor)->UseRealTime()->Unit(benchmark::kMillisecond);

void BM_SimulatedServoReferenceIntegrator(benchmark::State& state) { RunSimulatedServo(state, 50); }
BENCHMARK(BM_SimulatedServoReferenceIntegrator)->UseRealTime()->Unit(benchmark::kMillisecond);

// The plant alone. The constant command is 0.15 N above the breakaway friction, so the
// slide keeps sliding at a few tens of mm/s (the friction model is evaluated every
// substep); its sign alternates between 1 s iterations so the slide shuttles inside
// the travel instead of resting on an end stop.
void BM_PlantWriteOnly(benchmark::State& state) {
  const PlantOptions plant_options = SeedPlant(PlantOptions{}.substeps);
  SimulatedCatheter plant(plant_options);
  plant.ResetTo(-10.0);
  plant.Configure();
  plant.Activate();
  const std::size_t c_force = plant.CommandIndex(echoservo::hw::iface::kActuatorForce);
  const std::size_t s_tip = plant.StateIndex(echoservo::hw::iface::kTipPosition);
  const double force_n = plant.model().FrictionLevelN() + 0.15;
  const double dt = 1e-3;

  std::size_t k = 0;
  double sign = 1.0;
  for (auto _ : state) {
    plant.set_command(c_force, sign * force_n);
    for (std::size_t i = 0; i < kCyclesPerIteration; ++i, ++k) {
      const double t = static_cast<double>(k) * dt;
      plant.read(t, dt);
      benchmark::DoNotOptimize(plant.state(s_tip));
      plant.write(t, dt);
    }
    sign = -sign;
  }
  const auto iterations = static_cast<double>(state.iterations());
  SetRateCounters(state, iterations * static_cast<double>(kCyclesPerIteration) * dt,
                  iterations * static_cast<double>(kCyclesPerIteration));
  state.counters["substeps"] = plant_options.substeps;
  state.counters["force_n"] = force_n;
}
BENCHMARK(BM_PlantWriteOnly)->UseRealTime()->Unit(benchmark::kMillisecond);

// One friction evaluation, at speeds cycling over 0–255 mm/s.
void BM_TransmissionModelFriction(benchmark::State& state, const PlantOptions& plant_options) {
  const SimulatedCatheter plant(plant_options);
  const echoservo::hw::TransmissionModel& model = plant.model();
  unsigned i = 0;
  for (auto _ : state) {
    const double speed = static_cast<double>(i++ & 255u);
    benchmark::DoNotOptimize(speed);
    benchmark::DoNotOptimize(model.FrictionMagnitudeN(speed));
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["effects"] = static_cast<double>(model.effect_names().size());
}
BENCHMARK_CAPTURE(BM_TransmissionModelFriction, seed_calibrated, SeedPlant(10))->UseRealTime();
BENCHMARK_CAPTURE(BM_TransmissionModelFriction, seed_model,
                  echoservo::hw::SeedModelPlant(echoservo::hw::SeedTrackingCatheter()))
    ->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  benchmark::AddCustomContext("plant", "SeedCalibratedPlant(SeedTrackingCatheter()), 1 kHz servo");
  benchmark::AddCustomContext("servo",
                              "SeedServoConfig(plant, friction_feedforward = true), "
                              "AdaptiveInverse, 5 mm 1 Hz sine");
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
