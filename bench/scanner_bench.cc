// The simulated 3D ultrasound scanner (imaging/sim): volumes per second at the Philips
// size 160×148×208 from 128×64 beams × 512 samples, on 2 TBB threads (the platform's 2
// cores), and the cost of its stages. Counter "vol/s" is wall-clock volumes per second.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <memory>

#include "control/trajectory.h"
#include "imaging/sim/probe.h"
#include "imaging/sim/simulated_scanner.h"

namespace {

using echoservo::imaging::Volume;
using namespace echoservo::imaging::sim;

void BM_ScannerNext(benchmark::State& state) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(state.range(0)));
  const echoservo::control::MitralTrajectory traj;
  SimulatedScannerOptions o;
  o.catheter = state.range(1) != 0;
  o.target_displacement_mm = [&traj](double t) { return traj.Evaluate(t).position_mm; };
  SimulatedScanner scanner(o);
  for (auto _ : state) {
    auto f = scanner.Next();
    benchmark::DoNotOptimize(f->volume.voxels().data());
  }
  state.counters["vol/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ScannerNext)
    ->ArgNames({"threads", "catheter"})
    ->Args({2, 1})
    ->Args({1, 1})
    ->Args({2, 0})
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

void BM_ScanConversion(benchmark::State& state) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(state.range(0)));
  ProbeGeometry probe;
  ScanConverter conv(probe);
  std::vector<std::uint8_t> polar(probe.polar_size(), 100);
  Volume v = Volume::Create(conv.geometry());
  for (auto _ : state) {
    conv.Convert(polar, v);
    benchmark::DoNotOptimize(v.voxels().data());
  }
  state.counters["vol/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ScanConversion)
    ->ArgNames({"threads"})
    ->Arg(2)
    ->Arg(1)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

void BM_ScannerConstruction(benchmark::State& state) {
  for (auto _ : state) {
    auto s = std::make_unique<SimulatedScanner>(SimulatedScannerOptions{});
    benchmark::DoNotOptimize(s.get());
  }
}
BENCHMARK(BM_ScannerConstruction)->UseRealTime()->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace

BENCHMARK_MAIN();
