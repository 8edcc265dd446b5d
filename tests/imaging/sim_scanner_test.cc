#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "control/trajectory.h"
#include "imaging/sim/probe.h"
#include "imaging/sim/scene.h"
#include "imaging/sim/simulated_scanner.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo::imaging::sim {
namespace {

using ::testing::HasSubstr;

// Median over the voxels inside the pyramid (mostly water: dark).
double MedianInsideVoxel(const Volume& v) {
  const ProbeGeometry probe;
  std::vector<std::uint8_t> vals;
  for (int k = 0; k < v.dims().z(); k += 2)
    for (int j = 0; j < v.dims().y(); j += 2)
      for (int i = 0; i < v.dims().x(); i += 2) {
        Eigen::Vector3d q;
        if (probe.ToPolar(v.IndexToPhysical(Eigen::Vector3d(i, j, k)), &q))
          vals.push_back(v.at(i, j, k));
      }
  if (vals.empty()) return 0;
  std::nth_element(vals.begin(), vals.begin() + static_cast<long>(vals.size() / 2), vals.end());
  return vals[vals.size() / 2];
}

// Brightest voxel value within `radius_mm` of p (image frame).
double MaxNear(const Volume& v, const Eigen::Vector3d& p, double radius_mm) {
  double best = 0;
  const Eigen::Vector3d c = v.PhysicalToIndex(p);
  const Eigen::Vector3d r = radius_mm * v.spacing_mm().cwiseInverse();
  for (int k = static_cast<int>(std::floor(c.z() - r.z()));
       k <= static_cast<int>(std::ceil(c.z() + r.z())); ++k)
    for (int j = static_cast<int>(std::floor(c.y() - r.y()));
         j <= static_cast<int>(std::ceil(c.y() + r.y())); ++j)
      for (int i = static_cast<int>(std::floor(c.x() - r.x()));
           i <= static_cast<int>(std::ceil(c.x() + r.x())); ++i) {
        if (i < 0 || j < 0 || k < 0 || i >= v.dims().x() || j >= v.dims().y() || k >= v.dims().z())
          continue;
        if ((v.IndexToPhysical(Eigen::Vector3d(i, j, k)) - p).norm() > radius_mm) continue;
        best = std::max(best, static_cast<double>(v.at(i, j, k)));
      }
  return best;
}

// Mean of the brightest voxels near the axis over the last `length_mm` before the tip.
double AxisBrightness(const Volume& v, const Eigen::Vector3d& tip, const Eigen::Vector3d& dir,
                      double length_mm) {
  double sum = 0;
  int n = 0;
  for (double s = 0.5; s <= length_mm; s += 1.0, ++n) sum += MaxNear(v, tip - s * dir, 1.2);
  return sum / n;
}

// Mean of Sample() along the ray from the image origin through p, from |p| + a to |p| + b mm.
double MeanBehind(const Volume& v, const Eigen::Vector3d& p, double a, double b) {
  const Eigen::Vector3d u = p.normalized();
  double sum = 0;
  int n = 0;
  for (double s = p.norm() + a; s <= p.norm() + b; s += 0.25) {
    const double x = v.Sample(s * u);
    if (std::isnan(x)) continue;
    sum += x;
    ++n;
  }
  return n ? sum / n : 0.0;
}

TEST(SimScanner, GuidewireIsABrightLineAlongTheTruthAxis) {
  SimulatedScanner scanner({});
  const auto frame = scanner.Next();
  ASSERT_TRUE(frame.has_value());
  ASSERT_TRUE(frame->truth.has_value());
  const auto& t = *frame->truth;
  ASSERT_TRUE(t.catheter_visible);
  const double line = AxisBrightness(frame->volume, t.tip_mm, t.axis_direction, 20.0);
  const double median = MedianInsideVoxel(frame->volume);
  EXPECT_GT(line, median + 80.0) << "line " << line << " median " << median;
}

TEST(SimScanner, CatheterFreeVolumeHasNoBrightLine) {
  SimulatedScannerOptions o;
  o.catheter = false;
  SimulatedScanner scanner(o);
  const auto frame = scanner.Next();
  ASSERT_TRUE(frame->truth.has_value());
  EXPECT_FALSE(frame->truth->catheter_visible);
  // The default catheter's axis, where the wire would be.
  SimulatedScanner with_catheter({});
  const auto ref = with_catheter.Next();
  const auto& t = *ref->truth;
  const double line = AxisBrightness(frame->volume, t.tip_mm, t.axis_direction, 20.0);
  const double median = MedianInsideVoxel(frame->volume);
  EXPECT_LT(line, median + 40.0) << "line " << line << " median " << median;
}

TEST(SimScanner, TruthLiesInsideTheVolume) {
  SimulatedScanner scanner({});
  const auto frame = scanner.Next();
  const auto& t = *frame->truth;
  const auto box = frame->volume.BoundingBoxMm();
  EXPECT_TRUE(t.catheter_visible);
  EXPECT_TRUE(t.target_visible);
  EXPECT_TRUE(box.contains(t.tip_mm));
  EXPECT_TRUE(box.contains(t.axis_point_mm));
  EXPECT_TRUE(box.contains(t.target_mm));
  EXPECT_NEAR(t.axis_direction.norm(), 1.0, 1e-9);
  // Target on the axis, beyond the tip by gap − thickness/2 = 13.5 mm (scaled).
  const double along = (t.target_mm - t.tip_mm).dot(t.axis_direction);
  EXPECT_NEAR(along, 13.5 * scanner.depth_scale(), 0.05);
  EXPECT_LT(((t.target_mm - t.tip_mm) - along * t.axis_direction).norm(), 1e-3);
  // The target lies on tissue: bright-ish voxels near it.
  EXPECT_GT(MaxNear(frame->volume, t.target_mm, 1.5), MedianInsideVoxel(frame->volume) + 30.0);
}

SimulatedScannerOptions SingleReflector(double depth_mm, double sound_speed) {
  SimulatedScannerOptions o;
  o.catheter = false;
  o.annulus = false;
  o.tank = false;
  o.medium_sound_speed_m_s = sound_speed;
  SimulatedScannerOptions::ExtraMesh plate;
  plate.mesh = MakeBox({-6, -6, depth_mm}, {6, 6, depth_mm + 1.0});
  plate.properties = AcousticProperties::TankWall();
  o.extra_meshes.push_back(plate);
  return o;
}

double BrightestDepthOnCentralBeam(const Volume& v) {
  double best = -1, best_z = 0;
  for (double z = 10; z < 115; z += 0.05) {
    const double x = v.Sample(Eigen::Vector3d(0, 0, z));
    if (x > best) {
      best = x;
      best_z = z;
    }
  }
  return best_z;
}

TEST(SimScanner, SpeedOfSoundScalesDisplayedDepth) {
  ECHOSERVO_RELEASE_SUITE_ONLY("three full renders; the renderer's paths run in the other cases");
  const double d = 60.0;
  for (double c : {1482.0, 1540.0, 1600.0}) {
    SimulatedScanner scanner(SingleReflector(d, c));
    const auto frame = scanner.Next();
    EXPECT_NEAR(BrightestDepthOnCentralBeam(frame->volume), d * 1540.0 / c, 0.35) << "c = " << c;
    EXPECT_NEAR(scanner.WorldToImage(Eigen::Vector3d(0, 0, d)).z(), d * 1540.0 / c, 1e-9);
  }
}

TEST(SimScanner, SheathShadowsWhatIsBehindIt) {
  SimulatedScannerOptions with;
  SimulatedScannerOptions without;
  without.catheter = false;
  SimulatedScanner a(with), b(without);
  const auto fa = a.Next(), fb = b.Next();
  const auto& t = *fa->truth;
  // A point on the sheath, 20 mm proximal to its end.
  const Eigen::Vector3d p = t.axis_point_mm - 20.0 * t.axis_direction;
  const double behind_with = MeanBehind(fa->volume, p, 4.0, 60.0);
  const double behind_without = MeanBehind(fb->volume, p, 4.0, 60.0);
  EXPECT_LT(behind_with, 0.8 * behind_without) << behind_with << " vs " << behind_without;
}

TEST(SimScanner, GuidewireReverberatesDeeperAlongTheBeam) {
  SimulatedScannerOptions on;
  SimulatedScannerOptions off;
  off.reverberation = false;
  SimulatedScanner a(on), b(off);
  const auto fa = a.Next(), fb = b.Next();
  const auto& t = *fa->truth;
  const Eigen::Vector3d p = t.tip_mm - 4.0 * t.axis_direction;  // on the protruding wire
  const double tail_on = MeanBehind(fa->volume, p, 1.5, 6.0);
  const double tail_off = MeanBehind(fb->volume, p, 1.5, 6.0);
  EXPECT_GT(tail_on, tail_off + 20.0) << tail_on << " vs " << tail_off;
  // Nothing changes in front of the wire.
  EXPECT_NEAR(MeanBehind(fa->volume, p, -15.0, -3.0), MeanBehind(fb->volume, p, -15.0, -3.0), 1e-9);
}

TEST(SimScanner, DeterministicForAFixedSeed) {
  ECHOSERVO_RELEASE_SUITE_ONLY("five full renders compared; the renderer runs in the other cases");
  SimulatedScannerOptions o;
  o.seed = 7;
  SimulatedScanner a(o), b(o);
  for (int i = 0; i < 2; ++i) {
    const auto fa = a.Next(), fb = b.Next();
    ASSERT_TRUE(std::equal(fa->volume.voxels().begin(), fa->volume.voxels().end(),
                           fb->volume.voxels().begin()));
  }
  o.seed = 8;
  SimulatedScanner c(o);
  SimulatedScanner d([] {
    SimulatedScannerOptions x;
    x.seed = 7;
    return x;
  }());
  const auto fc = c.Next(), fd = d.Next();
  EXPECT_FALSE(std::equal(fc->volume.voxels().begin(), fc->volume.voxels().end(),
                          fd->volume.voxels().begin()));
}

TEST(SimScanner, StreamTimestampsIndicesAndEnd) {
  SimulatedScannerOptions o;
  o.rate_hz = 20.0;
  o.start_time_s = 1.0;
  o.max_frames = 3;
  SimulatedScanner s(o);
  EXPECT_DOUBLE_EQ(s.nominal_rate_hz(), 20.0);
  for (int i = 0; i < 3; ++i) {
    const auto f = s.Next();
    ASSERT_TRUE(f.has_value());
    EXPECT_EQ(f->volume.frame_index(), i);
    EXPECT_DOUBLE_EQ(f->volume.timestamp_s(), 1.0 + i / 20.0);
    EXPECT_EQ(f->volume.dims(), Eigen::Vector3i(160, 148, 208));
  }
  EXPECT_FALSE(s.Next().has_value());
}

TEST(SimScanner, TargetFollowsTheMitralTrajectoryAndTipTheCatheterAdvance) {
  const control::MitralTrajectory traj;
  SimulatedScannerOptions o;
  o.target_displacement_mm = [&traj](double t) { return traj.Evaluate(t).position_mm; };
  o.catheter_pose_at = [](double t) {
    CatheterPose p;
    p.advance_mm = 5.0 * t;
    return p;
  };
  SimulatedScanner s(o);
  const auto f0 = s.Render(0.0);
  const auto f1 = s.Render(0.3);
  const double k = s.depth_scale();
  const Eigen::Vector3d dir = f0.truth->axis_direction;
  const double moved = (f1.truth->target_mm - f0.truth->target_mm).dot(dir);
  EXPECT_NEAR(moved, k * (traj.Evaluate(0.3).position_mm - traj.Evaluate(0.0).position_mm), 0.02);
  EXPECT_NEAR((f1.truth->tip_mm - f0.truth->tip_mm).dot(dir), k * 1.5, 1e-6);
}

TEST(SimScanner, OptionErrorsNameTheField) {
  auto expect_field = [](SimulatedScannerOptions o, const std::string& field) {
    try {
      SimulatedScanner s(std::move(o));
      ADD_FAILURE() << "no error for " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_THAT(e.what(), HasSubstr(field));
    }
  };
  SimulatedScannerOptions o;
  o.rate_hz = 0;
  expect_field(o, "rate_hz");
  o = {};
  o.medium_sound_speed_m_s = 300;
  expect_field(o, "medium_sound_speed_m_s");
  o = {};
  o.probe.n_azimuth = 1;
  expect_field(o, "n_azimuth");
  o = {};
  o.probe.volume_dims = Eigen::Vector3i(0, 10, 10);
  expect_field(o, "dims");
  o = {};
  o.catheter_geometry.wire_diameter_mm = 3.0;
  expect_field(o, "wire_diameter_mm");
  o = {};
  o.dynamic_range_db = std::nan("");
  expect_field(o, "dynamic_range_db");
  o = {};
  o.probe_to_world.linear() *= 2.0;
  expect_field(o, "probe_to_world");
  EXPECT_THROW(MakeCylinder(-1, 10), std::invalid_argument);
  AcousticProperties p;
  p.transmission = 2;
  EXPECT_THROW(p.Validate(), std::invalid_argument);
}

TEST(SimScene, TraceAllFindsEntryAndExitWithIncidence) {
  Scene scene;
  const int id =
      scene.AddMesh(MakeCylinder(1.0, 20.0), AcousticProperties::Sheath(),
                    Eigen::Isometry3d(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY())) *
                        Eigen::Translation3d(0, 0, -10));  // axis along world x
  scene.Commit();
  RayHit hits[4];
  // Along +z from below: crosses the cylinder (axis x, radius 1) at z = ±1.
  const int n = scene.TraceAll(Eigen::Vector3f(0, 0, -10), Eigen::Vector3f(0, 0, 1), 100, hits, 4);
  ASSERT_EQ(n, 2);
  EXPECT_NEAR(hits[0].t_mm, 9.0, 0.02);
  EXPECT_NEAR(hits[1].t_mm, 11.0, 0.02);
  EXPECT_TRUE(hits[0].entering);
  EXPECT_FALSE(hits[1].entering);
  EXPECT_EQ(hits[0].mesh, id);
  EXPECT_GT(hits[0].cos_incidence, 0.98f);
}

TEST(SimScene, LoadsObj) {
  const std::string path = ::testing::TempDir() + "/sim_tri.obj";
  {
    FILE* f = std::fopen(path.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1 2/2 3/3 4/4\n", f);
    std::fclose(f);
  }
  const TriangleMesh m = LoadMeshFile(path);
  EXPECT_EQ(m.vertices.size(), 4u);
  EXPECT_EQ(m.triangles.size(), 2u);
  EXPECT_THROW(LoadMeshFile("/nonexistent.obj"), std::invalid_argument);
  EXPECT_THROW(LoadMeshFile("mesh.ply"), std::invalid_argument);
}

}  // namespace
}  // namespace echoservo::imaging::sim
