// One 3D ultrasound volume: uint8 voxels on a regular grid, placed in space.
//
// Frames: voxel index (i, j, k), x fastest, integer indices at voxel centres; the image frame
// is the MetaImage physical space in mm, physical_mm = origin_mm + direction · (index ⊙
// spacing_mm), `direction` columns the unit index axes. ImageToProbe (image → probe) and
// ProbeToReference (probe → tracker reference) are rigid, in mm. Time in s on the stream's
// acquisition clock. Geometry is fixed at creation and validated before any voxel memory is
// allocated; pose and time stamps can be updated.
// Errors: std::invalid_argument naming the field (see Validate and the setters).
// Notation: docs/architecture.md#units-frames-and-naming
// Details: docs/imaging.md#volumes-and-frames-imagingvolumeh
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

namespace echoservo::imaging {

// Where the voxel grid lies in the image frame. Plain data; Validate() says what is wrong.
struct VolumeGeometry {
  static constexpr int kMaxDim = 4096;                     // voxels per axis
  static constexpr std::int64_t kMaxVoxels = 512LL << 20;  // 512 Mi voxels (512 MiB)
  static constexpr double kOrthonormalTolerance = 1e-6;    // on |directionᵀ·direction − I|

  Eigen::Vector3i dims = Eigen::Vector3i::Ones();           // voxel counts (x, y, z)
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones();     // voxel pitch along i, j, k
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();      // centre of voxel (0,0,0)
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();  // columns: index axes

  // Throws std::invalid_argument naming the offending field (`where` prefixes the message)
  // when: a dim is outside [1, kMaxDim]; the voxel count exceeds kMaxVoxels; a spacing is
  // not finite and > 0; the origin is not finite; the direction is not finite or not
  // orthonormal within kOrthonormalTolerance (reflections, det = −1, are allowed).
  void Validate(const std::string& where = "volume geometry") const;
  // Exactly equal dims, spacing, origin and direction.
  bool operator==(const VolumeGeometry& other) const;

  // dims.x · dims.y · dims.z, computed without overflow for any int dims.
  std::int64_t VoxelCount() const;
};

class Volume {
 public:
  // Validates `geometry` (see VolumeGeometry::Validate) and only then allocates the voxels,
  // all set to `fill`.
  static Volume Create(const VolumeGeometry& geometry, std::uint8_t fill = 0);

  const VolumeGeometry& geometry() const { return geometry_; }
  const Eigen::Vector3i& dims() const { return geometry_.dims; }
  const Eigen::Vector3d& spacing_mm() const { return geometry_.spacing_mm; }
  const Eigen::Vector3d& origin_mm() const { return geometry_.origin_mm; }
  const Eigen::Matrix3d& direction() const { return geometry_.direction; }
  std::size_t voxel_count() const { return voxels_.size(); }

  // Voxel (i, j, k); the indices must lie in [0, dims) (asserted).
  std::uint8_t& at(int i, int j, int k) { return voxels_[LinearIndex(i, j, k)]; }
  std::uint8_t at(int i, int j, int k) const { return voxels_[LinearIndex(i, j, k)]; }
  // All voxels, x fastest (i + dims.x · (j + dims.y · k)), as stored in a MetaImage file.
  std::span<std::uint8_t> voxels() { return voxels_; }
  std::span<const std::uint8_t> voxels() const { return voxels_; }

  // Continuous index (voxel units) → image-frame point (mm), and back. Exact inverses up to
  // rounding: the inverse of direction · diag(spacing) is computed once, not assumed to be
  // its transpose.
  Eigen::Vector3d IndexToPhysical(const Eigen::Vector3d& index) const;
  Eigen::Vector3d PhysicalToIndex(const Eigen::Vector3d& physical_mm) const;
  // The linear part of PhysicalToIndex: (direction · diag(spacing_mm))⁻¹.
  const Eigen::Matrix3d& physical_to_index() const { return physical_to_index_; }

  // Trilinear interpolation of the voxel values at an image-frame point (mm). The volume
  // is defined between voxel centres, i.e. for continuous indices in [0, dims − 1] on each
  // axis (a 1-voxel axis accepts only index 0); a point outside, or a non-finite one,
  // returns quiet NaN. A margin of kInsideToleranceIndex voxel absorbs rounding, so the
  // corner voxel centres themselves sample exactly. (VolumeSampler below: the same, inlined.)
  static constexpr double kInsideToleranceIndex = 1e-9;
  double Sample(const Eigen::Vector3d& physical_mm) const;

  // Axis-aligned box, in the image frame (mm), around the 8 corner voxel centres: the region
  // where Sample() is defined whenever the direction is axis-aligned, and its hull otherwise.
  Eigen::AlignedBox3d BoundingBoxMm() const;

  // Pose of the volume. Setters throw std::invalid_argument naming the field when the
  // transform is not finite or its linear part is not a rotation (within 1e-6).
  // has_image_to_probe(): whether the image-to-probe transform is known (the scanning geometry:
  // where the beams come from). False until set_image_to_probe; image_to_probe() is then the
  // identity by convention only (e.g. a volume reconstructed from many probe poses has none).
  const Eigen::Isometry3d& image_to_probe() const { return image_to_probe_; }
  bool has_image_to_probe() const { return has_image_to_probe_; }
  const Eigen::Isometry3d& probe_to_reference() const { return probe_to_reference_; }
  void set_image_to_probe(const Eigen::Isometry3d& image_to_probe);
  void set_probe_to_reference(const Eigen::Isometry3d& probe_to_reference);
  // probe_to_reference · image_to_probe.
  Eigen::Isometry3d ImageToReference() const { return probe_to_reference_ * image_to_probe_; }

  // Acquisition time (s) and frame number in the stream. set_timestamp_s throws for a
  // non-finite time.
  double timestamp_s() const { return timestamp_s_; }
  std::int64_t frame_index() const { return frame_index_; }
  void set_timestamp_s(double timestamp_s);
  void set_frame_index(std::int64_t frame_index) { frame_index_ = frame_index; }

 private:
  explicit Volume(const VolumeGeometry& geometry, std::uint8_t fill);

  std::size_t LinearIndex(int i, int j, int k) const {
    assert(i >= 0 && i < geometry_.dims.x() && "Volume::at: i out of range");
    assert(j >= 0 && j < geometry_.dims.y() && "Volume::at: j out of range");
    assert(k >= 0 && k < geometry_.dims.z() && "Volume::at: k out of range");
    const auto nx = static_cast<std::size_t>(geometry_.dims.x());
    const auto ny = static_cast<std::size_t>(geometry_.dims.y());
    return static_cast<std::size_t>(i) +
           nx * (static_cast<std::size_t>(j) + ny * static_cast<std::size_t>(k));
  }

  VolumeGeometry geometry_;
  Eigen::Matrix3d index_to_physical_;  // direction · diag(spacing_mm)
  Eigen::Matrix3d physical_to_index_;  // its inverse
  std::vector<std::uint8_t> voxels_;

  Eigen::Isometry3d image_to_probe_ = Eigen::Isometry3d::Identity();
  bool has_image_to_probe_ = false;
  Eigen::Isometry3d probe_to_reference_ = Eigen::Isometry3d::Identity();
  double timestamp_s_ = 0.0;
  std::int64_t frame_index_ = 0;
};

// Volume::Sample for loops that take thousands of samples (profiles, tube checks): inlined,
// the geometry copied once; Volume::Sample calls it, so the values are the same. Holds a
// pointer to the voxels: valid while the volume lives.
class VolumeSampler {
 public:
  explicit VolumeSampler(const Volume& v)
      : dims_(v.dims()),
        origin_(v.origin_mm()),
        to_index_(v.physical_to_index()),
        voxels_(v.voxels().data()) {}

  double operator()(const Eigen::Vector3d& physical_mm) const {
    const Eigen::Vector3d index = to_index_ * (physical_mm - origin_);
    int base[3];
    double frac[3];
    for (int a = 0; a < 3; ++a) {
      const double last = dims_[a] - 1;
      // Written so that NaN fails the test too.
      if (!(index[a] >= -Volume::kInsideToleranceIndex &&
            index[a] <= last + Volume::kInsideToleranceIndex))
        return std::numeric_limits<double>::quiet_NaN();
      const double c = std::clamp(index[a], 0.0, last);
      // Lower neighbour in [0, dims − 2] so that base + 1 is valid; a 1-voxel axis uses 0
      // twice. c ≥ 0: truncation is floor (std::floor is a library call without SSE 4.1).
      base[a] = std::max(0, std::min(static_cast<int>(c), dims_[a] - 2));
      frac[a] = c - base[a];
    }
    const std::ptrdiff_t sx = dims_.x() > 1 ? 1 : 0, sy = dims_.y() > 1 ? dims_.x() : 0,
                         sz =
                             dims_.z() > 1 ? static_cast<std::ptrdiff_t>(dims_.x()) * dims_.y() : 0;
    const std::uint8_t* b0 = voxels_ + base[0] +
                             static_cast<std::ptrdiff_t>(dims_.x()) *
                                 (base[1] + static_cast<std::ptrdiff_t>(dims_.y()) * base[2]);
    double value = 0.0;
    for (int corner = 0; corner < 8; ++corner) {
      const int dx = corner & 1, dy = (corner >> 1) & 1, dz = (corner >> 2) & 1;
      const double w = (dx ? frac[0] : 1.0 - frac[0]) * (dy ? frac[1] : 1.0 - frac[1]) *
                       (dz ? frac[2] : 1.0 - frac[2]);
      // No branch on w = 0 (a corner outside a 1-voxel axis repeats a valid one): it adds 0.
      value += w * b0[dx * sx + dy * sy + dz * sz];
    }
    return value;
  }

 private:
  Eigen::Vector3i dims_;
  Eigen::Vector3d origin_;
  Eigen::Matrix3d to_index_;
  const std::uint8_t* voxels_;
};

}  // namespace echoservo::imaging
