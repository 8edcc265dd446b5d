// A cube of n³ voxels of `spacing` mm filled with one value: the blank canvas the detector
// tests draw lines and surfaces on.
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "imaging/volume.h"

namespace echoservo::testing {

inline imaging::Volume Synthetic(int n, double spacing_mm, std::uint8_t fill) {
  imaging::VolumeGeometry g;
  g.dims = Eigen::Vector3i(n, n, n);
  g.spacing_mm = Eigen::Vector3d::Constant(spacing_mm);
  return imaging::Volume::Create(g, fill);
}

}  // namespace echoservo::testing
