#include "imaging/volume.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

namespace echoservo::imaging {
namespace {

using ::testing::HasSubstr;

// 90° about z, written out exactly: index axis i points along image +y, j along −x, k along +z.
Eigen::Matrix3d QuarterTurnAboutZ() {
  Eigen::Matrix3d d;
  d << 0, -1, 0,  //
      1, 0, 0,    //
      0, 0, 1;
  return d;
}

VolumeGeometry RotatedGeometry() {
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(10, 8, 6);
  g.spacing_mm = Eigen::Vector3d(0.5, 2.0, 3.0);
  g.origin_mm = Eigen::Vector3d(10.0, 20.0, 30.0);
  g.direction = QuarterTurnAboutZ();
  return g;
}

// Expects `geometry` to be rejected with a message that names `field`.
void ExpectRejected(const VolumeGeometry& geometry, const std::string& field) {
  try {
    (void)Volume::Create(geometry);
    ADD_FAILURE() << "expected std::invalid_argument naming " << field;
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("'" + field + "'"));
    EXPECT_THAT(e.what(), HasSubstr("Volume::Create"));
  }
}

TEST(Volume, CreateAllocatesFilledVoxelsInMetaImageOrder) {
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(4, 3, 2);
  Volume v = Volume::Create(g, 7);
  EXPECT_EQ(v.voxel_count(), 24u);
  EXPECT_EQ(v.voxels().size(), 24u);
  EXPECT_EQ(v.at(3, 2, 1), 7);
  v.at(1, 0, 0) = 1;
  v.at(0, 1, 0) = 2;
  v.at(0, 0, 1) = 3;
  v.at(3, 2, 1) = 4;
  // x fastest, then y, then z.
  EXPECT_EQ(v.voxels()[1], 1);
  EXPECT_EQ(v.voxels()[4], 2);
  EXPECT_EQ(v.voxels()[12], 3);
  EXPECT_EQ(v.voxels()[23], 4);
  const Volume& cv = v;
  EXPECT_EQ(cv.at(0, 1, 0), 2);
}

TEST(Volume, IndexToPhysicalFollowsMetaImageConvention) {
  const Volume v = Volume::Create(RotatedGeometry());
  // index ⊙ spacing = (0.5, 4, 9); direction · that = (−4, 0.5, 9); + origin.
  const Eigen::Vector3d p = v.IndexToPhysical(Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(p, Eigen::Vector3d(6.0, 20.5, 39.0));
  EXPECT_EQ(v.IndexToPhysical(Eigen::Vector3d::Zero()), Eigen::Vector3d(10, 20, 30));
  const Eigen::Vector3d back = v.PhysicalToIndex(Eigen::Vector3d(6.0, 20.5, 39.0));
  EXPECT_NEAR((back - Eigen::Vector3d(1, 2, 3)).norm(), 0.0, 1e-14);
}

TEST(Volume, IndexPhysicalRoundTripWithGenericRotation) {
  VolumeGeometry g = RotatedGeometry();
  g.direction = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix() *
                Eigen::Vector3d(1, -1, 1).asDiagonal();  // a reflection: det = −1 is allowed
  const Volume v = Volume::Create(g);
  for (const Eigen::Vector3d& index :
       {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(9, 7, 5), Eigen::Vector3d(2.25, 6.5, 0.125),
        Eigen::Vector3d(-3, 100, 1e3)}) {
    const Eigen::Vector3d p = v.IndexToPhysical(index);
    // The index axes are orthonormal: the physical step along i is spacing.x · column 0.
    EXPECT_NEAR(
        (v.IndexToPhysical(index + Eigen::Vector3d::UnitX()) - p - 0.5 * g.direction.col(0)).norm(),
        0.0, 1e-12);
    EXPECT_NEAR((v.PhysicalToIndex(p) - index).norm(), 0.0, 1e-12 * (1.0 + index.norm()));
  }
}

TEST(Volume, TrilinearSampleOfLinearRampIsExact) {
  for (const Eigen::Matrix3d& direction :
       {Eigen::Matrix3d(Eigen::Matrix3d::Identity()), QuarterTurnAboutZ(),
        Eigen::Matrix3d(
            Eigen::AngleAxisd(1.1, Eigen::Vector3d(-1, 0.5, 2).normalized()).toRotationMatrix())}) {
    VolumeGeometry g = RotatedGeometry();
    g.direction = direction;
    Volume v = Volume::Create(g);
    // value = 2i + 3j + 5k ≤ 18 + 21 + 25 = 64 fits in uint8.
    for (int k = 0; k < 6; ++k)
      for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 10; ++i)
          v.at(i, j, k) = static_cast<std::uint8_t>(2 * i + 3 * j + 5 * k);
    const auto ramp = [](const Eigen::Vector3d& c) { return 2 * c.x() + 3 * c.y() + 5 * c.z(); };
    for (const Eigen::Vector3d& index :
         {Eigen::Vector3d(2.25, 3.5, 1.75), Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(9, 7, 5),
          Eigen::Vector3d(8.9, 0.01, 4.5), Eigen::Vector3d(4, 5, 2),
          Eigen::Vector3d(0.5, 6.999, 5)}) {
      EXPECT_NEAR(v.Sample(v.IndexToPhysical(index)), ramp(index), 1e-9) << index.transpose();
    }
    EXPECT_NEAR(v.Sample(v.IndexToPhysical(Eigen::Vector3d(2.25, 3.5, 1.75))), 23.75, 1e-9);
  }
}

TEST(Volume, SampleIsNaNOutsideTheVoxelCentres) {
  Volume v = Volume::Create(RotatedGeometry(), 100);
  EXPECT_DOUBLE_EQ(v.Sample(v.IndexToPhysical(Eigen::Vector3d(9, 7, 5))), 100.0);
  for (const Eigen::Vector3d& index : {Eigen::Vector3d(-0.01, 3, 3), Eigen::Vector3d(9.01, 3, 3),
                                       Eigen::Vector3d(4, 7.5, 3), Eigen::Vector3d(4, 3, -1)}) {
    EXPECT_TRUE(std::isnan(v.Sample(v.IndexToPhysical(index)))) << index.transpose();
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(std::isnan(v.Sample(Eigen::Vector3d(nan, 20, 30))));
}

TEST(Volume, SingleSliceAxisSamplesOnlyOnItsPlane) {
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(3, 3, 1);
  Volume v = Volume::Create(g);
  v.at(1, 1, 0) = 40;
  v.at(2, 1, 0) = 80;
  EXPECT_DOUBLE_EQ(v.Sample(Eigen::Vector3d(1.5, 1.0, 0.0)), 60.0);
  EXPECT_DOUBLE_EQ(v.Sample(Eigen::Vector3d(1.0, 0.5, 0.0)), 20.0);
  EXPECT_TRUE(std::isnan(v.Sample(Eigen::Vector3d(1.5, 1.0, 0.1))));
}

TEST(Volume, BoundingBoxOfRotatedVolume) {
  const Volume v = Volume::Create(RotatedGeometry());
  // Last voxel centre: index (9, 7, 5) ⊙ spacing = (4.5, 14, 15); i → +y, j → −x, k → +z.
  const Eigen::AlignedBox3d box = v.BoundingBoxMm();
  EXPECT_EQ(box.min(), Eigen::Vector3d(10.0 - 14.0, 20.0, 30.0));
  EXPECT_EQ(box.max(), Eigen::Vector3d(10.0, 20.0 + 4.5, 30.0 + 15.0));
}

TEST(Volume, PoseAndTime) {
  Volume v = Volume::Create(RotatedGeometry());
  EXPECT_TRUE(v.ImageToReference().isApprox(Eigen::Isometry3d::Identity()));
  Eigen::Isometry3d image_to_probe = Eigen::Isometry3d::Identity();
  image_to_probe.translate(Eigen::Vector3d(0, 0, 5));  // image origin 5 mm below the probe face
  Eigen::Isometry3d probe_to_reference(
      Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitX()));
  probe_to_reference.pretranslate(Eigen::Vector3d(100, 0, 0));
  v.set_image_to_probe(image_to_probe);
  v.set_probe_to_reference(probe_to_reference);
  // (1, 2, 3) → probe (1, 2, 8) → rotated about x: (1, −8, 2) → + (100, 0, 0).
  EXPECT_NEAR(
      (v.ImageToReference() * Eigen::Vector3d(1, 2, 3) - Eigen::Vector3d(101, -8, 2)).norm(), 0.0,
      1e-12);
  v.set_timestamp_s(12.5);
  v.set_frame_index(42);
  EXPECT_EQ(v.timestamp_s(), 12.5);
  EXPECT_EQ(v.frame_index(), 42);

  EXPECT_THROW(v.set_timestamp_s(std::numeric_limits<double>::infinity()), std::invalid_argument);
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 2.0;  // not rigid
  try {
    v.set_image_to_probe(scaled);
    ADD_FAILURE() << "expected a throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("'image_to_probe'"));
  }
  Eigen::Isometry3d mirrored = Eigen::Isometry3d::Identity();
  mirrored.linear()(2, 2) = -1.0;  // orthonormal but a reflection
  EXPECT_THROW(v.set_probe_to_reference(mirrored), std::invalid_argument);
  EXPECT_TRUE(v.ImageToReference().isApprox(probe_to_reference * image_to_probe));  // unchanged
}

TEST(Volume, RejectsBadDims) {
  for (const Eigen::Vector3i& dims : {Eigen::Vector3i(0, 5, 5), Eigen::Vector3i(5, -1, 5)}) {
    VolumeGeometry g;
    g.dims = dims;
    ExpectRejected(g, dims.x() == 0 ? "dims.x" : "dims.y");
  }
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(5, 5, 4097);
  ExpectRejected(g, "dims.z");
  // 4096 · 4096 · 33 = 553,648,128 > 512 Mi = 536,870,912: rejected before allocating.
  g.dims = Eigen::Vector3i(4096, 4096, 33);
  ExpectRejected(g, "dims");
  g.dims = Eigen::Vector3i(4096, 4096, 32);  // exactly 512 Mi is allowed (not allocated here)
  EXPECT_NO_THROW(g.Validate());
}

TEST(Volume, RejectsBadSpacingOriginAndDirection) {
  for (double bad : {0.0, -0.5, std::nan(""), std::numeric_limits<double>::infinity()}) {
    VolumeGeometry g;
    g.spacing_mm.y() = bad;
    ExpectRejected(g, "spacing_mm.y");
  }
  VolumeGeometry g;
  g.origin_mm.z() = std::nan("");
  ExpectRejected(g, "origin_mm");

  g = VolumeGeometry();
  g.direction(0, 1) = std::nan("");
  ExpectRejected(g, "direction");
  g = VolumeGeometry();
  g.direction.col(0) *= 1.001;  // not unit length
  ExpectRejected(g, "direction");
  g = VolumeGeometry();
  g.direction.col(1) = Eigen::Vector3d(1, 1, 0).normalized();  // unit but not orthogonal
  ExpectRejected(g, "direction");
  g = VolumeGeometry();
  g.direction.col(0) *= 1.0 + 1e-7;  // within the 1e-6 tolerance
  EXPECT_NO_THROW(Volume::Create(g));
}

#ifndef NDEBUG
TEST(VolumeDeathTest, AtAssertsIndexBounds) {
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(4, 3, 2);
  const Volume v = Volume::Create(g);
  EXPECT_DEATH((void)v.at(4, 0, 0), "i out of range");
  EXPECT_DEATH((void)v.at(0, -1, 0), "j out of range");
  EXPECT_DEATH((void)v.at(0, 0, 2), "k out of range");
}
#endif

}  // namespace
}  // namespace echoservo::imaging
