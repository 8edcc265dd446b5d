// The heartbeat predictor's costs: one EKF measurement update (target ≤ 20 µs) and one
// 1 kHz evaluation of the exported Fourier motion (target ≤ 1 µs), beside the
// constant-velocity KF baseline's update in the same process. Binary:
// ${CMAKE_RUNTIME_OUTPUT_DIRECTORY}/echoservo_predictor_bench.
#include <benchmark/benchmark.h>

#include "control/synthetic_motion.h"
#include "estimation/heartbeat_ekf.h"
#include "estimation/motion_trace.h"

namespace {

using echoservo::estimation::HeartbeatEkf;

echoservo::estimation::MotionTrace Measurements() {
  const auto m = echoservo::control::MakeSyntheticMotion(echoservo::control::MitralHrvDefaults());
  return echoservo::estimation::ResampleTrace(m.measured, 25.0);
}

// A filter initialised on the first 5 s; the benchmark then feeds the rest, cycling
// (times shifted by the trace length so they keep increasing).
template <class Filter>
void Feed(benchmark::State& state, Filter& filter) {
  static const echoservo::estimation::MotionTrace trace = Measurements();
  std::size_t i = 0;
  while (trace.t_s[i] < 5.0) filter.Update(trace.t_s[i], trace.position_mm[i]), ++i;
  const std::size_t first = i;
  double shift = 0.0;
  for (auto _ : state) {
    filter.Update(trace.t_s[i] + shift, trace.position_mm[i]);
    if (++i == trace.size()) {
      i = first;
      shift += trace.duration_s();
    }
  }
}

void BM_EkfUpdate(benchmark::State& state) {
  echoservo::estimation::HeartbeatEkfOptions o;
  o.harmonics = static_cast<int>(state.range(0));
  o.respiration = state.range(1) != 0;
  HeartbeatEkf ekf(o);
  Feed(state, ekf);
}
BENCHMARK(BM_EkfUpdate)->Args({6, 0})->Args({6, 1})->Args({12, 1});

void BM_ConstantVelocityKfUpdate(benchmark::State& state) {
  echoservo::estimation::ConstantVelocityKf kf;
  Feed(state, kf);
}
BENCHMARK(BM_ConstantVelocityKfUpdate);

// The servo's 1 kHz call: position, velocity and acceleration of the exported model.
void BM_FourierMotionEvaluate(benchmark::State& state) {
  echoservo::estimation::HeartbeatEkfOptions o;
  o.harmonics = static_cast<int>(state.range(0));
  o.respiration = true;
  HeartbeatEkf ekf(o);
  const echoservo::estimation::MotionTrace trace = Measurements();
  for (std::size_t i = 0; i < trace.size() && trace.t_s[i] < 6.0; ++i)
    ekf.Update(trace.t_s[i], trace.position_mm[i]);
  const echoservo::estimation::FourierMotion motion = ekf.Motion();
  double t = motion.t0_s;
  for (auto _ : state) {
    benchmark::DoNotOptimize(motion.Evaluate(t));
    t += 0.001;
  }
}
BENCHMARK(BM_FourierMotionEvaluate)->Arg(6)->Arg(12);

// Exporting the model after an update (once per volume).
void BM_EkfExportMotion(benchmark::State& state) {
  HeartbeatEkf ekf;
  const echoservo::estimation::MotionTrace trace = Measurements();
  for (std::size_t i = 0; i < trace.size() && trace.t_s[i] < 6.0; ++i)
    ekf.Update(trace.t_s[i], trace.position_mm[i]);
  for (auto _ : state) benchmark::DoNotOptimize(ekf.Motion());
}
BENCHMARK(BM_EkfExportMotion);

}  // namespace

BENCHMARK_MAIN();
