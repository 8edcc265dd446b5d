// The search stage's building blocks (tracking/radon_transform.h): pooling, levels, regions of
// interest and the pruned searches give the same results as their plain definitions.
#include "tracking/radon_transform.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

namespace echoservo::tracking {
namespace {

// Odd dims (clipped pooling blocks at the far faces), anisotropic spacing, a rotated grid,
// speckle-like noise and a bright line.
imaging::Volume TestVolume(std::uint32_t seed) {
  imaging::VolumeGeometry g;
  g.dims = Eigen::Vector3i(45, 38, 31);
  g.spacing_mm = Eigen::Vector3d(0.55, 0.45, 0.6);
  g.origin_mm = Eigen::Vector3d(-10, 4, 30);
  g.direction = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  auto v = imaging::Volume::Create(g);
  std::mt19937 rng(seed);
  for (auto& x : v.voxels()) x = rng() % 4 == 0 ? 0 : static_cast<std::uint8_t>(30 + rng() % 50);
  const Eigen::Vector3d p0 = v.IndexToPhysical(Eigen::Vector3d(5, 10, 8));
  const Eigen::Vector3d p1 = v.IndexToPhysical(Eigen::Vector3d(40, 25, 22));
  const Line3 line{p0, (p1 - p0).normalized()};
  for (int k = 0; k < g.dims.z(); ++k)
    for (int j = 0; j < g.dims.y(); ++j)
      for (int i = 0; i < g.dims.x(); ++i) {
        const Eigen::Vector3d p = v.IndexToPhysical(Eigen::Vector3d(i, j, k));
        const double s = line.Parameter(p);
        if (s >= 0 && s <= (p1 - p0).norm() && PointToLineDistance(line, p) < 0.7)
          v.at(i, j, k) = 240;
      }
  return v;
}

// Max-pooling by definition: each voxel into its block.
std::vector<std::uint8_t> NaivePool(const imaging::Volume& v, int f, Eigen::Vector3i& dims) {
  const Eigen::Vector3i d = v.dims();
  dims = Eigen::Vector3i((d.x() + f - 1) / f, (d.y() + f - 1) / f, (d.z() + f - 1) / f);
  std::vector<std::uint8_t> out(static_cast<std::size_t>(dims.prod()), 0);
  for (int k = 0; k < d.z(); ++k)
    for (int j = 0; j < d.y(); ++j)
      for (int i = 0; i < d.x(); ++i) {
        auto& c = out[static_cast<std::size_t>(i / f + dims.x() * (j / f + dims.y() * (k / f)))];
        c = std::max(c, v.at(i, j, k));
      }
  return out;
}

void ExpectSameCells(const RadonLevel& a, const RadonLevel& b) {
  ASSERT_EQ(a.cells.size(), b.cells.size());
  for (std::size_t i = 0; i < a.cells.size(); ++i) {
    EXPECT_EQ(a.cells[i].p_mm, b.cells[i].p_mm) << i;
    EXPECT_EQ(a.cells[i].weight, b.cells[i].weight) << i;
  }
  EXPECT_EQ(a.background, b.background);
}

TEST(RadonTransform, PoolingAPooledGridEqualsPoolingTheVolume) {
  const auto v = TestVolume(1);
  for (int f : {2, 3}) {
    Eigen::Vector3i dims;
    const auto direct = NaivePool(v, 2 * f, dims);
    const PooledGrid twice = MaxPool(MaxPool(v, 2), f);
    EXPECT_EQ(twice.factor, 2 * f);
    EXPECT_EQ(twice.dims, dims);
    EXPECT_EQ(twice.values, direct) << f;
    std::array<std::int64_t, 256> h{};
    for (auto x : direct) ++h[x];
    EXPECT_EQ(twice.histogram, h);
  }
}

TEST(RadonTransform, MedianNonZeroVoxelIsTheMedianOfTheNonZeroVoxels) {
  const auto v = TestVolume(2);
  std::vector<std::uint8_t> nz;
  for (auto x : v.voxels())
    if (x) nz.push_back(x);
  std::sort(nz.begin(), nz.end());
  // The lower median (the first value reaching half of the count).
  EXPECT_EQ(MedianNonZeroVoxel(v), nz[(nz.size() - 1) / 2]);
  EXPECT_EQ(MedianNonZeroVoxel(imaging::Volume::Create(v.geometry(), 0)), 0.0);
}

TEST(RadonTransform, LevelOfAGridEqualsTheLevelOfTheVolume) {
  const auto v = TestVolume(3);
  for (int f : {1, 2, 4})
    ExpectSameCells(MakeRadonLevel(v, f, 1.0), MakeRadonLevel(v, MaxPool(v, f), 1.0));
}

TEST(RadonTransform, ContrastThresholdKeepsTheCellsClearlyAboveTheBackground) {
  const auto v = TestVolume(4);
  const PooledGrid grid = MaxPool(v, 2);
  const RadonLevel all = MakeRadonLevel(v, grid, 1.0);
  const RadonLevel bright = MakeRadonLevel(v, grid, 1.0, nullptr, 0.125);
  EXPECT_GT(bright.min_value, bright.background);
  EXPECT_LT(bright.cells.size(), all.cells.size() / 2);
  // The kept cells are those of the full level above the threshold, with the same weights.
  RadonLevel expected = all;
  std::erase_if(expected.cells, [&](const RadonCell& c) {
    return c.weight <= (bright.min_value - all.background) * (bright.min_value - all.background);
  });
  ExpectSameCells(expected, bright);
}

TEST(RadonTransform, RegionOfInterestLevelIsTheFullLevelNearTheLine) {
  const auto v = TestVolume(5);
  const Line3 axis{v.IndexToPhysical(Eigen::Vector3d(20, 18, 15)),
                   Eigen::Vector3d(1, 0.4, -0.3).normalized()};
  const RadonWindow roi{axis, 4.0};
  for (int f : {2, 4}) {
    const PooledGrid full = MaxPool(v, f);
    const LevelThresholds thresholds = GridThresholds(full, 0.125);
    RadonLevel expected = MakeRadonLevel(v, full, 1.0, nullptr, thresholds);
    std::erase_if(expected.cells, [&](const RadonCell& c) {
      return PointToLineDistance(axis, c.p_mm) > roi.radius_mm;
    });
    ASSERT_FALSE(expected.cells.empty());
    ExpectSameCells(expected, MakeRadonLevel(v, MaxPool(v, f, roi), 1.0, &roi, thresholds));
  }
}

// A region's nested grids: the coarse one is the volume's pooled grid of the region, cell
// for cell; the fine one gives the region's fine level.
TEST(RadonTransform, NestedRegionGridsAreTheRegionsGridsOfTheVolume) {
  const auto v = TestVolume(5);
  const Line3 axes[] = {
      Line3{v.IndexToPhysical(Eigen::Vector3d(20, 18, 15)),
            Eigen::Vector3d(1, 0.4, -0.3).normalized()},
      Line3{v.IndexToPhysical(Eigen::Vector3d(3, 30, 7)),
            Eigen::Vector3d(0.1, -1, 0.7).normalized()},
      Line3{v.IndexToPhysical(Eigen::Vector3d(11, 9, 21)), Eigen::Vector3d::UnitZ()}};
  // Every cell above the background: the speckle as well as the line.
  const LevelThresholds thresholds = GridThresholds(MaxPool(v, 2), 0.0);
  for (const Line3& axis : axes)
    for (double radius : {2.0, 5.0}) {
      const RadonWindow roi{axis, radius};
      const NestedGrids g = MaxPoolNested(v, 2, 2, roi);
      const PooledGrid coarse = MaxPool(v, 4, roi);
      EXPECT_EQ(g.coarse.factor, 4);
      EXPECT_EQ(g.fine.factor, 2);
      EXPECT_EQ(g.coarse.dims, coarse.dims);
      ASSERT_GT(std::count_if(coarse.values.begin(), coarse.values.end(),
                              [](std::uint8_t x) { return x > 0; }),
                0);
      EXPECT_EQ(g.coarse.values, coarse.values) << "radius " << radius;
      const RadonLevel fine = MakeRadonLevel(v, MaxPool(v, 2, roi), 1.0, &roi, thresholds);
      ASSERT_FALSE(fine.cells.empty());
      ExpectSameCells(fine, MakeRadonLevel(v, g.fine, 1.0, &roi, thresholds));
    }
}

TEST(RadonTransform, WindowedSearchEqualsTheBestWindowedPeakOfEachDirection) {
  const auto v = TestVolume(6);
  const RadonLevel level = MakeRadonLevel(v, 2, 1.0);
  const auto coarse = SearchDirections(level, FibonacciHemisphere(400), nullptr);
  const RadonWindow window{PeakLine(level, coarse.direction, coarse.peak), 3.0};
  const auto cone = DirectionCone(coarse.direction, 0.1, 7);
  const auto r = SearchDirections(level, cone, &window);
  // Reference: every direction's full histogram, peaks restricted to the window afterwards.
  double best = -1;
  for (const auto& d : cone) {
    const auto peaks = RadonPeaks(level, d, &window, false);
    if (!peaks.empty()) best = std::max(best, peaks.front().score);
  }
  EXPECT_GT(best, 0);
  EXPECT_EQ(r.peak.score, best);
}

TEST(RadonTransform, CoarseToFineSearchFindsTheBestDirectionOfTheSet) {
  const auto v = TestVolume(7);
  const RadonLevel level = MakeRadonLevel(v, 2, 1.0);
  const auto dirs = FibonacciHemisphere(600);
  const auto all = SearchDirections(level, dirs, nullptr);
  const auto c2f = SearchDirectionsCoarseToFine(level, dirs);
  EXPECT_EQ(c2f.peak.score, all.peak.score);
  EXPECT_EQ(c2f.direction, all.direction);
  // The statistics come from the first stage: every other direction of the set.
  ASSERT_EQ(c2f.scores.size(), dirs.size() / 2);
  for (std::size_t i = 0; i < c2f.scores.size(); ++i)
    EXPECT_EQ(c2f.scores[i], all.scores[2 * i]) << i;
}

// The fine refinement's two-stage cone search gives the full cone grid's best direction near a
// line (its score is smooth there), from the sub-grid and the neighbours of its best.
TEST(RadonTransform, ConeCoarseToFineFindsTheGridsBestNearALine) {
  const auto v = TestVolume(11);
  const RadonLevel level = MakeRadonLevel(v, 2, 1.0);
  const Eigen::Vector3d p0 = v.IndexToPhysical(Eigen::Vector3d(5, 10, 8));
  const Eigen::Vector3d p1 = v.IndexToPhysical(Eigen::Vector3d(40, 25, 22));
  const Eigen::Vector3d truth = (p1 - p0).normalized();
  for (const double tilt_rad : {0.0, 0.03, 0.06}) {
    Eigen::Vector3d u, w;
    PlaneBasis(truth, u, w);
    const Eigen::Vector3d start = (truth + std::tan(tilt_rad) * u).normalized();
    const RadonWindow near{Line3{p0, start}, 3.0};
    for (const int steps : {8, 9}) {
      const auto grid = SearchDirections(level, DirectionCone(start, 0.08, steps), &near);
      const auto c2f = SearchConeCoarseToFine(level, start, 0.08, steps, 3, &near);
      EXPECT_EQ(c2f.peak.score, grid.peak.score) << tilt_rad << " " << steps;
      EXPECT_EQ(c2f.direction, grid.direction) << tilt_rad << " " << steps;
      // The first stage is the sub-grid: every other row and column and the last ones.
      const std::size_t side = static_cast<std::size_t>((steps + 2) / 2);
      EXPECT_EQ(c2f.scores.size(), side * side);
    }
  }
}

}  // namespace
}  // namespace echoservo::tracking
