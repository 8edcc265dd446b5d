// Test frames for the PLUS sequence writer and reader tests: volumes whose every voxel, index,
// timestamp and pose depend on the frame number, so a frame out of place or altered shows.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "imaging/io/plus_sequence.h"
#include "imaging/volume.h"

namespace echoservo::imaging::test_frames {

inline VolumeGeometry Geometry(int nx = 24, int ny = 20, int nz = 16) {
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(nx, ny, nz);
  g.spacing_mm = Eigen::Vector3d(0.5, 0.6, 0.7);
  g.origin_mm = Eigen::Vector3d(-5.0, 2.0, 10.0);
  g.direction = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return g;
}

// Frame i: every voxel a function of i and its index, so a frame out of place shows.
inline Volume Frame(int i, const VolumeGeometry& g = Geometry()) {
  Volume v = Volume::Create(g);
  auto px = v.voxels();
  for (std::size_t k = 0; k < px.size(); ++k)
    px[k] = static_cast<std::uint8_t>((k * 7 + static_cast<std::size_t>(i) * 31) & 0xff);
  v.set_frame_index(100 + i);
  v.set_timestamp_s(12.5 + 0.04 * i);
  Eigen::Isometry3d image_to_probe = Eigen::Isometry3d::Identity();
  image_to_probe.translation() = Eigen::Vector3d(1.0, -2.0, 0.25 * i);
  v.set_image_to_probe(image_to_probe);
  return v;
}

// `got` (frame `frame` of a sequence) is Frame(i).
inline void ExpectFrame(const Volume& got, std::size_t frame, int i) {
  const Volume expected = Frame(i);
  EXPECT_TRUE(got.geometry() == expected.geometry());
  EXPECT_EQ(got.frame_index(), expected.frame_index());
  EXPECT_DOUBLE_EQ(got.timestamp_s(), expected.timestamp_s());
  EXPECT_TRUE(got.image_to_probe().isApprox(expected.image_to_probe(), 1e-12));
  ASSERT_TRUE(std::equal(got.voxels().begin(), got.voxels().end(), expected.voxels().begin(),
                         expected.voxels().end()))
      << "frame " << frame;
}

inline void ExpectFrame(const PlusSequence& s, std::size_t frame, int i) {
  ExpectFrame(SequenceFrameToVolume(s, frame), frame, i);
}

}  // namespace echoservo::imaging::test_frames
