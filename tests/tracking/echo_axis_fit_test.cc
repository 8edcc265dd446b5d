// Near-wall tube model of tracking/echo_axis_fit.h on synthetic echoes with known geometry.
#include "tracking/echo_axis_fit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "tests/test_util/constants.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::tracking {
namespace {

using testing::kDeg;

// A catheter seen by beams from the probe apex at the image origin (image_to_probe =
// identity): only the near wall echoes, as a Gaussian blob of σ 0.3 mm at the point of the
// tube (radius 1.25 mm up to `sheath_end`, 0.45 mm beyond it) facing the apex.
struct Scene {
  Eigen::Vector3d p0{-15.0, 0.3, 60.0};
  Eigen::Vector3d dir = Eigen::Vector3d(1.0, 0.1, 0.2).normalized();
  double sheath_end = 30.0, tip = 38.0;  // mm along dir from p0
  double R = 1.25, rho = 0.45;
};

imaging::Volume Render(const Scene& sc) {
  imaging::VolumeGeometry g;
  g.dims = Eigen::Vector3i(100, 40, 50);
  g.spacing_mm = Eigen::Vector3d(0.5, 0.5, 0.4);
  g.origin_mm = Eigen::Vector3d(-20, -10, 50);
  auto v = imaging::Volume::Create(g, 10);
  v.set_image_to_probe(Eigen::Isometry3d::Identity());  // the beams are known
  for (double s = 0; s <= sc.tip; s += 0.1) {
    const Eigen::Vector3d a = sc.p0 + s * sc.dir;
    const Eigen::Vector3d b = a.normalized();  // beam from the apex (origin)
    const Eigen::Vector3d n = -(b - b.dot(sc.dir) * sc.dir).normalized();
    const Eigen::Vector3d e = a + (s < sc.sheath_end ? sc.R : sc.rho) * n;  // near-wall echo
    const Eigen::Vector3d c = v.PhysicalToIndex(e);
    for (int k = static_cast<int>(c.z()) - 3; k <= static_cast<int>(c.z()) + 4; ++k)
      for (int j = static_cast<int>(c.y()) - 3; j <= static_cast<int>(c.y()) + 4; ++j)
        for (int i = static_cast<int>(c.x()) - 3; i <= static_cast<int>(c.x()) + 4; ++i) {
          if (i < 0 || j < 0 || k < 0 || i >= g.dims.x() || j >= g.dims.y() || k >= g.dims.z())
            continue;
          const double d2 = (v.IndexToPhysical(Eigen::Vector3d(i, j, k)) - e).squaredNorm();
          const double val = 10 + 240 * std::exp(-d2 / (2 * 0.3 * 0.3));
          v.at(i, j, k) = static_cast<std::uint8_t>(std::max<double>(v.at(i, j, k), val));
        }
  }
  return v;
}

TEST(EchoAxisFit, RecoversTheAxisBehindTheNearWallEchoes) {
  const Scene sc;
  const auto v = Render(sc);
  const Line3 truth{sc.p0, sc.dir};
  // A start line 1 mm off and 2° tilted, as the Radon search might give.
  const Line3 start{sc.p0 + Eigen::Vector3d(0, 0, -1.0),
                    (sc.dir + Eigen::Vector3d(0, 0.035, 0)).normalized()};
  EchoAxisFitOptions o;
  o.sheath_diameter_mm = 2 * sc.R;
  o.wire_diameter_mm = 2 * sc.rho;
  const auto fit = FitEchoAxis(v, start, 10.0, o);
  ASSERT_TRUE(fit.has_value());
  // The echo line itself is tilted by the radius step (R − ρ over the echoes' length) and lies
  // ~R from the axis; the modelled axis is the true one (sub-voxel: 0.4–0.5 mm voxels).
  EXPECT_GT(AngleBetweenLines(fit->echo_line, truth) / kDeg, 0.5);
  EXPECT_LT(AngleBetweenLines(fit->axis, truth) / kDeg, 0.15);
  EXPECT_LT(PointToLineDistance(fit->axis, sc.p0 + sc.tip * sc.dir), 0.1);
  EXPECT_LT(PointToLineDistance(fit->axis, sc.p0), 0.1);
  ASSERT_TRUE(fit->wire_found);
  const Eigen::Vector3d bp = fit->axis.point + fit->sheath_end_s * fit->axis.direction;
  EXPECT_NEAR((bp - sc.p0).dot(sc.dir), sc.sheath_end, 0.5);
}

TEST(EchoAxisFit, ZeroDiametersReturnTheEchoLine) {
  const Scene sc;
  const auto v = Render(sc);
  EchoAxisFitOptions o;
  o.sheath_diameter_mm = 0;
  o.wire_diameter_mm = 0;
  const auto fit = FitEchoAxis(v, Line3{sc.p0, sc.dir}, 10.0, o);
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT(AngleBetweenLines(fit->axis, fit->echo_line), 1e-9);
  EXPECT_FALSE(fit->wire_found);
}

TEST(EchoAxisFit, NoEchoesNearTheLineGiveNothing) {
  imaging::VolumeGeometry g;
  g.dims = Eigen::Vector3i(20, 20, 20);
  const auto v = imaging::Volume::Create(g, 5);
  EXPECT_FALSE(FitEchoAxis(v, Line3{Eigen::Vector3d(10, 10, 10), Eigen::Vector3d::UnitX()}, 5.0, {})
                   .has_value());
}

TEST(EchoAxisFit, OptionsAreValidated) {
  EchoAxisFitOptions o;
  o.wire_diameter_mm = 3.0;  // thicker than the sheath
  testing::ExpectContains(testing::InvalidArgumentMessage([&] { o.Validate(); }),
                          "wire_diameter_mm");
  o = {};
  o.fit_radius_mm = -1;
  testing::ExpectContains(testing::InvalidArgumentMessage([&] { o.Validate(); }), "fit_radius_mm");
}

TEST(BeamDirection, RadiatesFromTheProbeApex) {
  imaging::VolumeGeometry g;
  g.dims = Eigen::Vector3i(4, 4, 4);
  auto v = imaging::Volume::Create(g);
  EXPECT_TRUE(BeamDirectionAt(v, Eigen::Vector3d(3, 0, 4)).isApprox(Eigen::Vector3d(0.6, 0, 0.8)));
  // Behind the apex: the probe's axis.
  EXPECT_TRUE(BeamDirectionAt(v, Eigen::Vector3d(0, 0, -4)).isApprox(Eigen::Vector3d::UnitZ()));
  Eigen::Isometry3d image_to_probe = Eigen::Isometry3d::Identity();
  image_to_probe.translation() = Eigen::Vector3d(0, 0, 10);  // apex at image z = −10
  v.set_image_to_probe(image_to_probe);
  EXPECT_TRUE(BeamDirectionAt(v, Eigen::Vector3d(0, 0, 0)).isApprox(Eigen::Vector3d::UnitZ()));
}

TEST(BeamGeometry, KnownOnlyWhenTheVolumeOrTheCallerSaysSo) {
  imaging::VolumeGeometry g;
  g.dims = Eigen::Vector3i(4, 4, 4);
  auto v = imaging::Volume::Create(g);
  EXPECT_FALSE(v.has_image_to_probe());
  EXPECT_FALSE(BeamGeometry::FromVolume(v).known());
  EXPECT_EQ(BeamGeometry::FromVolume(v).At(Eigen::Vector3d(1, 2, 3)), Eigen::Vector3d::Zero());
  Eigen::Isometry3d image_to_probe = Eigen::Isometry3d::Identity();
  image_to_probe.translation() = Eigen::Vector3d(0, 0, 10);  // apex at image z = −10
  v.set_image_to_probe(image_to_probe);
  EXPECT_TRUE(v.has_image_to_probe());
  const BeamGeometry b = BeamGeometry::FromVolume(v);
  ASSERT_EQ(b.kind, BeamGeometry::Kind::kApex);
  EXPECT_TRUE(b.At(Eigen::Vector3d(3, 0, -6)).isApprox(Eigen::Vector3d(0.6, 0, 0.8)));
  // A given apex: every beam from it; parallel beams: one direction everywhere.
  EXPECT_TRUE(BeamGeometry::FromApex(Eigen::Vector3d(1, 1, 1))
                  .At(Eigen::Vector3d(1, 4, 5))
                  .isApprox(Eigen::Vector3d(0, 0.6, 0.8)));
  EXPECT_TRUE(BeamGeometry::Parallel(Eigen::Vector3d(0, 0, 2))
                  .At(Eigen::Vector3d(7, -3, 1))
                  .isApprox(Eigen::Vector3d::UnitZ()));
  testing::ExpectContains(
      testing::InvalidArgumentMessage([] { BeamGeometry::Parallel(Eigen::Vector3d::Zero()); }),
      "non-zero");
  testing::ExpectContains(testing::InvalidArgumentMessage(
                              [] { BeamGeometry::FromApex(Eigen::Vector3d(0, std::nan(""), 0)); }),
                          "finite");
}

// A symmetric tube (a bright ring cross-section, as a volume compounded from many probe poses
// images it) without beam geometry: the fit is the centre line, no side preferred.
TEST(EchoAxisFit, UnknownBeamsGiveTheCentreLineOfASymmetricTube) {
  imaging::VolumeGeometry g;
  g.dims = Eigen::Vector3i(90, 40, 40);
  g.spacing_mm = Eigen::Vector3d(0.5, 0.45, 0.4);
  g.origin_mm = Eigen::Vector3d(-20, -9, 52);
  auto v = imaging::Volume::Create(g, 10);
  const Eigen::Vector3d p0(-15.0, 0.17, 60.23),
      dir = Eigen::Vector3d(1.0, 0.12, -0.08).normalized();
  for (int k = 0; k < g.dims.z(); ++k)
    for (int j = 0; j < g.dims.y(); ++j)
      for (int i = 0; i < g.dims.x(); ++i) {
        const Eigen::Vector3d p = v.IndexToPhysical(Eigen::Vector3d(i, j, k)) - p0;
        const double s = p.dot(dir), r = (p - s * dir).norm();
        if (s < 0 || s > 35) continue;
        const double ring = std::exp(-0.5 * std::pow((r - 1.25) / 0.35, 2));  // wall at R
        v.at(i, j, k) = static_cast<std::uint8_t>(10 + 240 * ring);
      }
  ASSERT_FALSE(v.has_image_to_probe());
  const auto fit = FitEchoAxis(v, Line3{p0 + Eigen::Vector3d(0, 0.8, -0.6), dir}, 10.0, {});
  ASSERT_TRUE(fit.has_value());
  const Line3 truth{p0, dir};
  EXPECT_LT(AngleBetweenLines(fit->axis, truth) / kDeg, 0.2);
  EXPECT_LT(PointToLineDistance(fit->axis, p0 + 5.0 * dir), 0.1);
  EXPECT_LT(PointToLineDistance(fit->axis, p0 + 30.0 * dir), 0.1);
  // The same volume told its beams come from above: the near-wall model shifts the axis by
  // the sheath radius away from the (upper) near wall, the side bias the unknown case avoids.
  const auto biased =
      FitEchoAxis(v, Line3{p0, dir}, 10.0, {}, BeamGeometry::Parallel(Eigen::Vector3d::UnitZ()));
  ASSERT_TRUE(biased.has_value());
  EXPECT_GT(PointToLineDistance(biased->axis, p0 + 15.0 * dir), 0.5);
}

}  // namespace
}  // namespace echoservo::tracking
