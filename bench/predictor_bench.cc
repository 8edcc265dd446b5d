// The heartbeat predictor's costs: one EKF measurement update (target ≤ 20 µs) and one
// 1 kHz evaluation of the exported Fourier motion (target ≤ 1 µs), beside the
// constant-velocity KF baseline's update in the same process; the predictor competition's
// full update (EKF, autoregressive predictor and the three baselines, with scoring and
// choice; target ≤ 20 µs) beside the EKF alone, on the synthetic trace and on a realistic
// one (ectopic beats, outliers, drops: re-acquisitions included). Binary:
// ${CMAKE_RUNTIME_OUTPUT_DIRECTORY}/echoservo_predictor_bench.
#include <benchmark/benchmark.h>

#include <memory>
#include <numbers>

#include "control/experiments/synthetic_motion.h"
#include "estimation/heartbeat_ekf.h"
#include "estimation/ls_ar_predictor.h"
#include "estimation/motion_trace.h"
#include "estimation/predictor_competition.h"
#include "estimation/realistic_heart_trace.h"
#include "estimation/slow_trend.h"

namespace {

using echoservo::estimation::HeartbeatEkf;

// Ten minutes of the synthetic trace, measured at 25 vol/s.
const echoservo::estimation::MotionTrace& Measurements() {
  static const echoservo::estimation::MotionTrace trace = [] {
    echoservo::control::SyntheticMotionOptions o = echoservo::control::MitralHrvDefaults();
    o.duration_s = 600.0;
    o.sample_rate_hz = 25.0;
    return echoservo::control::MakeSyntheticMotion(o).measured;
  }();
  return trace;
}

// A fresh filter is initialised on the first 5 s (untimed); the timed loop feeds one
// measurement per iteration and starts over (untimed) at the end of the trace.
template <class Make>
void Feed(benchmark::State& state, Make make) {
  const echoservo::estimation::MotionTrace& trace = Measurements();
  auto filter = make();
  std::size_t i = trace.size();
  for (auto _ : state) {
    if (i == trace.size()) {
      state.PauseTiming();
      filter = make();
      for (i = 0; trace.t_s[i] < 5.0; ++i) filter.Update(trace.t_s[i], trace.position_mm[i]);
      state.ResumeTiming();
    }
    filter.Update(trace.t_s[i], trace.position_mm[i]);
    ++i;
  }
}

void BM_EkfUpdate(benchmark::State& state) {
  echoservo::estimation::HeartbeatEkfOptions o;
  o.harmonics = static_cast<int>(state.range(0));
  // 0: respiration off, 1: on, 2: automatic (the default; its periodic trend check included).
  constexpr echoservo::estimation::Respiration kModes[] = {
      echoservo::estimation::Respiration::kOff, echoservo::estimation::Respiration::kOn,
      echoservo::estimation::Respiration::kAuto};
  o.respiration = kModes[state.range(1)];
  Feed(state, [&] { return HeartbeatEkf(o); });
}
BENCHMARK(BM_EkfUpdate)->Args({6, 0})->Args({6, 1})->Args({6, 2})->Args({12, 1})->Args({0, 2});

// Ten minutes of the realistic ectopic class at 25 vol/s (estimation/realistic_heart_trace.h).
const echoservo::estimation::MotionTrace& RealisticMeasurements() {
  static const echoservo::estimation::MotionTrace trace = [] {
    auto o = echoservo::estimation::RealisticHeartClass("ectopic", 1);
    o.duration_s = 600.0;
    return echoservo::estimation::GenerateRealisticHeartTrace(o);
  }();
  return trace;
}

// One measurement into the competition (every competitor updated, due predictions scored,
// the choice made, the next predictions stored) or into the EKF alone, default options;
// arg 0: the synthetic trace, 1: the realistic one.
template <class Make>
void FeedTrace(benchmark::State& state, const echoservo::estimation::MotionTrace& trace,
               Make make) {
  auto filter = make();
  std::size_t i = trace.size();
  for (auto _ : state) {
    if (i == trace.size()) {
      state.PauseTiming();
      filter = make();
      for (i = 0; trace.t_s[i] < 5.0; ++i) filter->Update(trace.t_s[i], trace.position_mm[i]);
      state.ResumeTiming();
    }
    filter->Update(trace.t_s[i], trace.position_mm[i]);
    ++i;
  }
}

void BM_CompetitionUpdate(benchmark::State& state) {
  FeedTrace(state, state.range(0) == 0 ? Measurements() : RealisticMeasurements(),
            [] { return std::make_unique<echoservo::estimation::PredictorCompetition>(); });
}
BENCHMARK(BM_CompetitionUpdate)->Arg(0)->Arg(1);

void BM_EkfAloneUpdate(benchmark::State& state) {
  FeedTrace(state, state.range(0) == 0 ? Measurements() : RealisticMeasurements(),
            [] { return std::make_unique<HeartbeatEkf>(); });
}
BENCHMARK(BM_EkfAloneUpdate)->Arg(0)->Arg(1);

void BM_ArUpdate(benchmark::State& state) {
  FeedTrace(state, state.range(0) == 0 ? Measurements() : RealisticMeasurements(),
            [] { return std::make_unique<echoservo::estimation::ArPredictor>(); });
}
BENCHMARK(BM_ArUpdate)->Arg(0)->Arg(1);

// The least-squares AR (Gram update every measurement, every candidate order solved every
// 0.5 s): the competition's extra cost beside the recursive AR above.
void BM_LsArUpdate(benchmark::State& state) {
  FeedTrace(state, state.range(0) == 0 ? Measurements() : RealisticMeasurements(),
            [] { return std::make_unique<echoservo::estimation::LsArPredictor>(); });
}
BENCHMARK(BM_LsArUpdate)->Arg(0)->Arg(1);

// (Re-)initialisation: the first 4 s (100 measurements) into a fresh filter, including
// the batch rate search and, with automatic harmonics, the harmonic-count choice.
void BM_EkfInitialisation(benchmark::State& state) {
  const echoservo::estimation::MotionTrace& trace = Measurements();
  echoservo::estimation::HeartbeatEkfOptions o;
  o.harmonics = static_cast<int>(state.range(0));
  for (auto _ : state) {
    HeartbeatEkf ekf(o);
    for (std::size_t i = 0; !ekf.initialised(); ++i) ekf.Update(trace.t_s[i], trace.position_mm[i]);
    benchmark::DoNotOptimize(ekf.rate_hz());
  }
}
BENCHMARK(BM_EkfInitialisation)->Arg(0)->Arg(6)->Unit(benchmark::kMillisecond);

// The automatic respiration check, once per 4 s window while the term is off: the
// slow-trend evidence of 100 measurements (4 s at 25 vol/s) at N harmonics; the update
// that runs it costs this much more.
void BM_SlowTrendEvidence(benchmark::State& state) {
  const echoservo::estimation::MotionTrace& trace = Measurements();
  echoservo::estimation::SlowTrendWindow window;
  window.Reset(static_cast<int>(state.range(0)), 4.0);
  for (std::size_t i = 0; i < 100; ++i)
    window.Add(trace.t_s[i], 2.0 * std::numbers::pi * 1.2 * trace.t_s[i], trace.position_mm[i]);
  for (auto _ : state) benchmark::DoNotOptimize(window.Evidence());
}
BENCHMARK(BM_SlowTrendEvidence)->Arg(6)->Arg(12);

void BM_ConstantVelocityKfUpdate(benchmark::State& state) {
  Feed(state, [] { return echoservo::estimation::ConstantVelocityKf(); });
}
BENCHMARK(BM_ConstantVelocityKfUpdate);

// The servo's 1 kHz call: position, velocity and acceleration of the exported model.
void BM_FourierMotionEvaluate(benchmark::State& state) {
  echoservo::estimation::HeartbeatEkfOptions o;
  o.harmonics = static_cast<int>(state.range(0));
  o.respiration = echoservo::estimation::Respiration::kOn;
  HeartbeatEkf ekf(o);
  const echoservo::estimation::MotionTrace& trace = Measurements();
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
  const echoservo::estimation::MotionTrace& trace = Measurements();
  for (std::size_t i = 0; i < trace.size() && trace.t_s[i] < 6.0; ++i)
    ekf.Update(trace.t_s[i], trace.position_mm[i]);
  for (auto _ : state) benchmark::DoNotOptimize(ekf.Motion());
}
BENCHMARK(BM_EkfExportMotion);

}  // namespace

BENCHMARK_MAIN();
