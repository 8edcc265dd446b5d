// Freehand reconstruction benchmark (Google Benchmark): the real PLUS N-wire sweep
// (data/plus/NwirePhantomFreehand.igs.mha, 97 frames of 820×616) at 0.5 mm with
// imaging::ReconstructFreehand (weighted splat + hole filling, and nearest), against the
// simplest nearest-neighbour loop written plainly here (for each pixel: transform with a
// 4×4 matrix, round to a voxel, store) in the same process, on the same frames and grid.
// Binary: build/bin/echoservo_reconstruct_bench [--benchmark_repetitions=N].
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "imaging/io/plus_sequence.h"
#include "imaging/reconstruct/freehand_reconstruction.h"

namespace {

using namespace echoservo::imaging;

// PLUS's nominal fCal Image→Probe (docs/reconstruction.md).
Eigen::Matrix4d Calibration() {
  Eigen::Matrix4d m;
  m << 0, 0.08, 0, 11, -0.08, 0, 0, 50, 0, 0, 0.08, 0, 0, 0, 0, 1;
  return m;
}

const PlusSequence& Sweep() {
  static const PlusSequence s =
      ReadPlusSequence(std::string(ECHOSERVO_DATA_DIR) + "/plus/NwirePhantomFreehand.igs.mha");
  return s;
}

void BM_Reconstruct(benchmark::State& state, Compounding method, bool fill) {
  ReconstructionOptions o;
  o.image_to_probe = Calibration();
  o.compounding = method;
  o.fill_holes = fill;
  std::int64_t voxels = 0;
  for (auto _ : state) {
    ReconstructionResult r = ReconstructFreehand(Sweep(), o);
    voxels = r.volume.voxel_count();
    benchmark::DoNotOptimize(r.volume.voxels().data());
  }
  state.counters["voxels"] = static_cast<double>(voxels);
  state.counters["frames"] = static_cast<double>(Sweep().frames.size());
}

// The plain loop: same grid as the reconstructor (bounding box of the corner pixels at
// 0.5 mm), every pixel through the full 4×4 product, rounded, stored (last value wins).
void BM_NaiveNearest(benchmark::State& state) {
  const PlusSequence& s = Sweep();
  const int w = s.frame_dims[0], h = s.frame_dims[1];
  std::vector<Eigen::Matrix4d> m;
  for (const SequenceFrame& f : s.frames)
    m.push_back(*f.Transform("ProbeToTracker") * Calibration());
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const Eigen::Matrix4d& t : m) {
    for (int cj : {0, h - 1}) {
      for (int ci : {0, w - 1}) {
        const Eigen::Vector3d p = (t * Eigen::Vector4d(ci, cj, 0, 1)).head<3>();
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
    }
  }
  const double spacing = 0.5;
  const int nx = static_cast<int>((hi.x() - lo.x()) / spacing) + 1;
  const int ny = static_cast<int>((hi.y() - lo.y()) / spacing) + 1;
  const int nz = static_cast<int>((hi.z() - lo.z()) / spacing) + 1;
  for (auto _ : state) {
    std::vector<std::uint8_t> volume(static_cast<std::size_t>(nx) * ny * nz, 0);
    for (std::size_t f = 0; f < m.size(); ++f) {
      const std::uint8_t* pixels = s.pixels.data() + f * s.FrameBytes();
      for (int j = 0; j < h; ++j) {
        for (int i = 0; i < w; ++i) {
          const Eigen::Vector4d p = m[f] * Eigen::Vector4d(i, j, 0, 1);
          const long x = std::lround((p.x() - lo.x()) / spacing);
          const long y = std::lround((p.y() - lo.y()) / spacing);
          const long z = std::lround((p.z() - lo.z()) / spacing);
          if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) continue;
          volume[x + static_cast<std::size_t>(nx) * (y + static_cast<std::size_t>(ny) * z)] =
              pixels[j * w + i];
        }
      }
    }
    benchmark::DoNotOptimize(volume.data());
  }
  state.counters["voxels"] = static_cast<double>(nx) * ny * nz;
}

BENCHMARK(BM_NaiveNearest)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Reconstruct, nearest_nofill, Compounding::kNearestLast, false)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Reconstruct, weighted_nofill, Compounding::kWeighted, false)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Reconstruct, weighted_fill, Compounding::kWeighted, true)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
