#include "imaging/volume.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace echoservo::imaging {
namespace {

void Require(bool ok, const std::string& where, const std::string& field, const std::string& why) {
  if (!ok) throw std::invalid_argument(where + ": field '" + field + "' " + why);
}

constexpr char kAxis[3] = {'x', 'y', 'z'};

std::string Short(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", value);
  return text;
}

// A rigid transform's linear part must be a proper rotation and its entries finite.
void RequireRigid(const Eigen::Isometry3d& transform, const std::string& field) {
  const Eigen::Matrix<double, 3, 4> top = transform.matrix().topRows<3>();
  Require(top.allFinite(), "Volume", field, "must have finite entries");
  const Eigen::Matrix3d r = transform.linear();
  const double orthonormality_error =
      (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  Require(orthonormality_error <= VolumeGeometry::kOrthonormalTolerance && r.determinant() > 0.0,
          "Volume", field,
          "must be rigid: its linear part must be a rotation (orthonormal, det = +1, within 1e-6)");
}

}  // namespace

std::int64_t VolumeGeometry::VoxelCount() const {
  // Three ints can overflow int64 (2^31·2^31·2^31); saturate so Validate() still rejects.
  std::int64_t count = 1;
  for (int a = 0; a < 3; ++a) {
    const std::int64_t d = dims[a];
    if (d <= 0) return 0;
    if (count > std::numeric_limits<std::int64_t>::max() / d)
      return std::numeric_limits<std::int64_t>::max();
    count *= d;
  }
  return count;
}

bool VolumeGeometry::operator==(const VolumeGeometry& o) const {
  return dims == o.dims && spacing_mm == o.spacing_mm && origin_mm == o.origin_mm &&
         direction == o.direction;
}

void VolumeGeometry::Validate(const std::string& where) const {
  for (int a = 0; a < 3; ++a) {
    Require(dims[a] >= 1 && dims[a] <= kMaxDim, where, std::string("dims.") + kAxis[a],
            "= " + std::to_string(dims[a]) + " must be a voxel count in [1, " +
                std::to_string(kMaxDim) + "]");
  }
  Require(VoxelCount() <= kMaxVoxels, where, "dims",
          "give " + std::to_string(VoxelCount()) + " voxels, more than the limit of " +
              std::to_string(kMaxVoxels) + " (512 Mi)");
  for (int a = 0; a < 3; ++a) {
    Require(std::isfinite(spacing_mm[a]) && spacing_mm[a] > 0.0, where,
            std::string("spacing_mm.") + kAxis[a], "must be a finite voxel pitch > 0 mm");
  }
  Require(origin_mm.allFinite(), where, "origin_mm", "must be finite");
  Require(direction.allFinite(), where, "direction", "must have finite entries");
  const double orthonormality_error =
      (direction.transpose() * direction - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  Require(orthonormality_error <= kOrthonormalTolerance, where, "direction",
          "must be orthonormal (columns are unit index axes; |DᵀD − I| = " +
              Short(orthonormality_error) + " > 1e-6)");
}

Volume Volume::Create(const VolumeGeometry& geometry, std::uint8_t fill) {
  geometry.Validate("Volume::Create");
  return Volume(geometry, fill);
}

Volume::Volume(const VolumeGeometry& geometry, std::uint8_t fill)
    : geometry_(geometry),
      index_to_physical_(geometry.direction * geometry.spacing_mm.asDiagonal()),
      physical_to_index_(index_to_physical_.inverse()),
      voxels_(static_cast<std::size_t>(geometry.VoxelCount()), fill) {}

Eigen::Vector3d Volume::IndexToPhysical(const Eigen::Vector3d& index) const {
  return geometry_.origin_mm + index_to_physical_ * index;
}

Eigen::Vector3d Volume::PhysicalToIndex(const Eigen::Vector3d& physical_mm) const {
  return physical_to_index_ * (physical_mm - geometry_.origin_mm);
}

double Volume::Sample(const Eigen::Vector3d& physical_mm) const {
  return VolumeSampler(*this)(physical_mm);
}

Eigen::AlignedBox3d Volume::BoundingBoxMm() const {
  Eigen::AlignedBox3d box;
  const Eigen::Vector3d last = (geometry_.dims - Eigen::Vector3i::Ones()).cast<double>();
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d index((corner & 1) ? last.x() : 0.0, (corner & 2) ? last.y() : 0.0,
                                (corner & 4) ? last.z() : 0.0);
    box.extend(IndexToPhysical(index));
  }
  return box;
}

void Volume::set_image_to_probe(const Eigen::Isometry3d& image_to_probe) {
  RequireRigid(image_to_probe, "image_to_probe");
  image_to_probe_ = image_to_probe;
  has_image_to_probe_ = true;
}

void Volume::set_probe_to_reference(const Eigen::Isometry3d& probe_to_reference) {
  RequireRigid(probe_to_reference, "probe_to_reference");
  probe_to_reference_ = probe_to_reference;
}

void Volume::set_timestamp_s(double timestamp_s) {
  Require(std::isfinite(timestamp_s), "Volume", "timestamp_s", "must be finite");
  timestamp_s_ = timestamp_s;
}

}  // namespace echoservo::imaging
