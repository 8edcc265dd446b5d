// The Radon catheter detector (tracking/radon_detector.h) on simulated 160×148×208 uint8
// volumes (SimulatedScanner, reverberation on), on 2 TBB threads (the platform's 2 cores)
// and on 1: a full search, tracking mode (Detect from the previous frame), and each stage
// alone. Issue 5's figures: ≤ 15 ms full search, ≤ 3 ms tracking, wall clock on 2 cores.
// "Time" is wall clock, "CPU" the whole process's CPU time (both threads). The volumes are
// rendered once; each benchmark cycles through them.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <Eigen/Geometry>
#include <numbers>
#include <vector>

#include "imaging/sim/catheter_scene.h"
#include "imaging/sim/simulated_scanner.h"
#include "tracking/axis_profile.h"
#include "tracking/echo_axis_fit.h"
#include "tracking/radon_detector.h"
#include "tracking/radon_transform.h"
#include "tracking/tube_check.h"

namespace {

using echoservo::imaging::Volume;
using echoservo::imaging::sim::SimulatedScanner;
using echoservo::imaging::sim::SimulatedScannerOptions;
using namespace echoservo::tracking;

struct Pose {
  double yaw_deg, tilt_deg, depth_mm, lateral_mm, sound_speed_m_s;
};

// Catheter and annulus poses as in tests/tracking/radon_detector_test.cc (Options()).
SimulatedScannerOptions ScannerOptions(const Pose& c) {
  SimulatedScannerOptions o;
  echoservo::imaging::sim::PlaceCatheterScene(
      {c.yaw_deg, c.tilt_deg, c.depth_mm, c.lateral_mm, 0.0}, o);
  o.medium_sound_speed_m_s = c.sound_speed_m_s;
  o.reverberation = true;
  return o;
}

// One rendered volume and the inputs of each stage, computed once as the detector does.
struct Sample {
  Sample(Volume v, CatheterDetection prior) : volume(std::move(v)), previous(std::move(prior)) {}
  Volume volume;
  // Tracking prior: the full search's detection in the frame before (the catheter 1 mm less
  // advanced).
  CatheterDetection previous;
  double background = 0;  // median non-zero voxel value
  PooledGrid fine_grid, coarse_grid;
  RadonLevel coarse, fine;
  RadonSearchResult coarse_best;
  Line3 search_line;  // the search's line (input of the fit)
  Line3 axis;         // the fitted axis
  TipEstimate tip;
};

const std::vector<Sample>& Samples() {
  static const std::vector<Sample> samples = [] {
    std::vector<Sample> out;
    const std::vector<Pose> poses = {{0, 10, 60, 0, 1482},
                                     {30, 5, 55, -5, 1482},
                                     {-20, 15, 70, 5, 1540},
                                     {180, 10, 50, 0, 1482}};
    const RadonDetectorOptions o;
    const RadonDetector detector(o);
    for (const auto& p : poses) {
      const SimulatedScannerOptions so = ScannerOptions(p);
      SimulatedScanner scanner(so);
      const CatheterDetection prior = detector.Detect(scanner.Next()->volume);
      scanner.SetCatheterPose({so.catheter_pose.base_to_world, so.catheter_pose.advance_mm + 1.0});
      Sample s(std::move(scanner.Next()->volume), prior);
      const Volume& v = s.volume;
      s.background = MedianNonZeroVoxel(v);
      s.fine_grid = MaxPool(v, 2);
      s.coarse_grid = MaxPool(s.fine_grid, 2);
      s.coarse =
          MakeRadonLevel(v, s.coarse_grid, o.max_depth_fraction, nullptr, o.level_min_contrast);
      s.fine = MakeRadonLevel(v, s.fine_grid, o.max_depth_fraction, nullptr, o.level_min_contrast);
      s.coarse_best = SearchDirections(s.coarse, FibonacciHemisphere(o.coarse_directions), nullptr);
      s.search_line = PeakLine(s.coarse, s.coarse_best.direction, s.coarse_best.peak);
      s.axis = FitEchoAxis(v, s.search_line, s.background, o.fit).value().axis;
      s.tip = FindTip(v, s.axis, s.background, o.edge);
      out.push_back(std::move(s));
    }
    return out;
  }();
  return samples;
}

// Runs `body(sample)` on the samples in turn, on state.range(0) TBB threads.
template <typename Body>
void Cycle(benchmark::State& state, Body body) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(state.range(0)));
  const auto& samples = Samples();
  std::size_t i = 0;
  for (auto _ : state) {
    body(samples[i]);
    i = (i + 1) % samples.size();
  }
}

#define DETECTOR_BENCHMARK(name) \
  BENCHMARK(name)                \
      ->ArgName("threads")       \
      ->Arg(2)                   \
      ->Arg(1)                   \
      ->UseRealTime()            \
      ->MeasureProcessCPUTime()  \
      ->Unit(benchmark::kMillisecond)

void BM_DetectFull(benchmark::State& state) {
  const RadonDetector detector;
  int found = 0;
  Cycle(state, [&](const Sample& s) {
    const auto d = detector.Detect(s.volume);
    found += d.found;
    benchmark::DoNotOptimize(d);
  });
  state.counters["found"] = benchmark::Counter(found, benchmark::Counter::kAvgIterations);
}
DETECTOR_BENCHMARK(BM_DetectFull);

// Tracking as in a stream (RadonDetector::Track): from the previous frame's detection,
// reusing its scene statistics.
void BM_DetectTracking(benchmark::State& state) {
  const RadonDetector detector;
  int tracked = 0;
  Cycle(state, [&](const Sample& s) {
    const auto d = detector.Detect(s.volume, s.previous);
    tracked += d.found && d.tracked;
    benchmark::DoNotOptimize(d);
  });
  // 1: every frame was tracked (no fallback to the full search).
  state.counters["tracked"] = benchmark::Counter(tracked, benchmark::Counter::kAvgIterations);
}
DETECTOR_BENCHMARK(BM_DetectTracking);

// Tracking from an axis alone: the scene statistics are measured on the volume as well.
void BM_DetectTrackingFromAxis(benchmark::State& state) {
  const RadonDetector detector;
  int tracked = 0;
  Cycle(state, [&](const Sample& s) {
    const auto d = detector.Detect(s.volume, s.previous.axis);
    tracked += d.found && d.tracked;
    benchmark::DoNotOptimize(d);
  });
  state.counters["tracked"] = benchmark::Counter(tracked, benchmark::Counter::kAvgIterations);
}
DETECTOR_BENCHMARK(BM_DetectTrackingFromAxis);

// Stages of the full search, in order.

void BM_Background(benchmark::State& state) {
  Cycle(state, [&](const Sample& s) { benchmark::DoNotOptimize(MedianNonZeroVoxel(s.volume)); });
}
DETECTOR_BENCHMARK(BM_Background);

// ×2 from the volume, ×4 from the ×2 grid.
void BM_MaxPool(benchmark::State& state) {
  Cycle(state, [&](const Sample& s) {
    const PooledGrid fine = MaxPool(s.volume, 2);
    const PooledGrid coarse = MaxPool(fine, 2);
    benchmark::DoNotOptimize(coarse.values.data());
  });
}
DETECTOR_BENCHMARK(BM_MaxPool);

void BM_MakeLevels(benchmark::State& state) {
  const RadonDetectorOptions o;
  Cycle(state, [&](const Sample& s) {
    const RadonLevel coarse = MakeRadonLevel(s.volume, s.coarse_grid, o.max_depth_fraction, nullptr,
                                             o.level_min_contrast);
    const RadonLevel fine =
        MakeRadonLevel(s.volume, s.fine_grid, o.max_depth_fraction, nullptr, o.level_min_contrast);
    benchmark::DoNotOptimize(fine.cells.data());
  });
}
DETECTOR_BENCHMARK(BM_MakeLevels);

// The old entry point: pooling and level in one call, ×4 and ×2 from the volume.
void BM_MakeRadonLevel(benchmark::State& state) {
  const int factor = static_cast<int>(state.range(1));
  Cycle(state, [&](const Sample& s) {
    const RadonLevel level = MakeRadonLevel(s.volume, factor, 1.0);
    benchmark::DoNotOptimize(level.cells.data());
  });
}
BENCHMARK(BM_MakeRadonLevel)
    ->ArgNames({"threads", "factor"})
    ->Args({2, 4})
    ->Args({2, 2})
    ->Args({1, 4})
    ->Args({1, 2})
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Unit(benchmark::kMillisecond);

// The hemisphere search as the detector runs it (coarse to fine over the directions).
void BM_SearchCoarse(benchmark::State& state) {
  const auto dirs = FibonacciHemisphere(RadonDetectorOptions{}.coarse_directions);
  Cycle(state, [&](const Sample& s) {
    const auto r = SearchDirectionsCoarseToFine(s.coarse, dirs);
    benchmark::DoNotOptimize(r.peak.score);
  });
}
DETECTOR_BENCHMARK(BM_SearchCoarse);

// Every direction of the hemisphere (reference for the coarse-to-fine search).
void BM_SearchCoarseAllDirections(benchmark::State& state) {
  const auto dirs = FibonacciHemisphere(RadonDetectorOptions{}.coarse_directions);
  Cycle(state, [&](const Sample& s) {
    const auto r = SearchDirections(s.coarse, dirs, nullptr);
    benchmark::DoNotOptimize(r.peak.score);
  });
}
DETECTOR_BENCHMARK(BM_SearchCoarseAllDirections);

// The two refinement passes on the ×2 level around the coarse line, as RadonDetector::Run.
void BM_SearchFine(benchmark::State& state) {
  const RadonDetectorOptions o;
  Cycle(state, [&](const Sample& s) {
    RadonWindow near{PeakLine(s.coarse, s.coarse_best.direction, s.coarse_best.peak),
                     2 * s.coarse.bin_mm};
    Eigen::Vector3d d = s.coarse_best.direction;
    double cone = o.fine_cone_rad;
    for (int pass = 0; pass < 2; ++pass) {
      const auto g = SearchDirections(s.fine, DirectionCone(d, cone, o.fine_steps), &near);
      if (g.peak.score > 0) {
        d = g.direction;
        near.line = PeakLine(s.fine, d, g.peak);
      }
      cone /= (o.fine_steps - 1) / 2.0;
    }
    benchmark::DoNotOptimize(RadonPeaks(s.fine, d, nullptr, false));
  });
}
DETECTOR_BENCHMARK(BM_SearchFine);

void BM_FitEchoAxis(benchmark::State& state) {
  const RadonDetectorOptions o;
  Cycle(state, [&](const Sample& s) {
    benchmark::DoNotOptimize(FitEchoAxis(s.volume, s.search_line, s.background, o.fit));
  });
}
DETECTOR_BENCHMARK(BM_FitEchoAxis);

void BM_FindTip(benchmark::State& state) {
  const RadonDetectorOptions o;
  Cycle(state, [&](const Sample& s) {
    benchmark::DoNotOptimize(FindTip(s.volume, s.axis, s.background, o.edge));
  });
}
DETECTOR_BENCHMARK(BM_FindTip);

void BM_FindTarget(benchmark::State& state) {
  const RadonDetectorOptions o;
  Cycle(state, [&](const Sample& s) {
    benchmark::DoNotOptimize(FindTarget(s.volume, s.tip, s.background, o.edge));
  });
}
DETECTOR_BENCHMARK(BM_FindTarget);

void BM_Tubularity(benchmark::State& state) {
  const RadonDetectorOptions o;
  Cycle(state, [&](const Sample& s) {
    const double to = s.tip.axis.Parameter(s.tip.tip_mm);
    benchmark::DoNotOptimize(Tubularity(s.volume, s.tip.axis, to - s.tip.line_length_mm, to,
                                        o.edge.dynamic_range_db, o.tube));
  });
}
DETECTOR_BENCHMARK(BM_Tubularity);

// Tracking mode's levels: the voxels near the previous axis only, pooled and thresholded
// with the previous frame's levels.
void BM_TrackingLevels(benchmark::State& state) {
  const RadonDetectorOptions o;
  Cycle(state, [&](const Sample& s) {
    const RadonWindow roi{s.previous.axis, o.tracking_window_mm + 4 * s.coarse.bin_mm};
    const RadonLevel coarse =
        MakeRadonLevel(s.volume, MaxPool(s.volume, 4, roi), o.max_depth_fraction, &roi,
                       s.previous.baseline.coarse);
    const RadonLevel fine = MakeRadonLevel(s.volume, MaxPool(s.volume, 2, roi),
                                           o.max_depth_fraction, &roi, s.previous.baseline.fine);
    benchmark::DoNotOptimize(fine.cells.data());
  });
}
DETECTOR_BENCHMARK(BM_TrackingLevels);

// The same levels as the detector builds them: the volume read once (MaxPoolNested).
void BM_TrackingLevelsNested(benchmark::State& state) {
  const RadonDetectorOptions o;
  Cycle(state, [&](const Sample& s) {
    const RadonWindow roi{s.previous.axis, o.tracking_window_mm + 4 * s.coarse.bin_mm};
    const NestedGrids g = MaxPoolNested(s.volume, 2, 2, roi);
    const RadonLevel coarse =
        MakeRadonLevel(s.volume, g.coarse, o.max_depth_fraction, &roi, s.previous.baseline.coarse);
    const RadonLevel fine =
        MakeRadonLevel(s.volume, g.fine, o.max_depth_fraction, &roi, s.previous.baseline.fine);
    benchmark::DoNotOptimize(coarse.cells.data());
    benchmark::DoNotOptimize(fine.cells.data());
  });
}
DETECTOR_BENCHMARK(BM_TrackingLevelsNested);

}  // namespace

BENCHMARK_MAIN();
