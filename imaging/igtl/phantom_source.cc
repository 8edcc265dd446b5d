#include "imaging/igtl/phantom_source.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

namespace echoservo::imaging::openigtlink {

PhantomSource::PhantomSource(PhantomOptions options) : options_(std::move(options)) {
  geometry_.dims = options_.dims;
  geometry_.spacing_mm = Eigen::Vector3d::Constant(options_.spacing_mm);
  geometry_.Validate("phantom geometry");
  const auto n = static_cast<std::size_t>(geometry_.VoxelCount());
  noise_.resize(n + 64);
  std::uint32_t s = options_.seed ? options_.seed : 1;
  for (auto& v : noise_) {  // xorshift32, sum of two draws: a skewed speckle-like spread
    s ^= s << 13;
    s ^= s >> 17;
    s ^= s << 5;
    const std::uint32_t a = s & 0xFF, b = (s >> 8) & 0xFF;
    v = static_cast<std::uint8_t>(10 + (a * b) / 1100);
  }
}

std::optional<SourceFrame> PhantomSource::Next() {
  if (options_.frame_count >= 0 && index_ >= options_.frame_count) return std::nullopt;
  Volume volume = Volume::Create(geometry_);
  const auto n = volume.voxel_count();
  const std::size_t shift = static_cast<std::size_t>(index_ % 64);
  std::memcpy(volume.voxels().data(), noise_.data() + shift, n);

  const double rate = options_.rate_hz > 0 ? options_.rate_hz : 30.0;
  const double t = static_cast<double>(index_) / rate;
  const Eigen::Vector3d dims = geometry_.dims.cast<double>();
  const Eigen::Vector3d centre = (dims - Eigen::Vector3d::Ones()) / 2.0;

  // The line ("catheter"), in index space, drawn with a 1-voxel radius.
  const Eigen::Vector3d a = dims.cwiseProduct(Eigen::Vector3d(0.2, 0.5, 0.1));
  const Eigen::Vector3d b = centre;
  const Eigen::Vector3d dir = (b - a).normalized();
  const double len = (b - a).norm();
  for (double s = 0; s <= len; s += 0.5) {
    const Eigen::Vector3d p = a + s * dir;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int i = static_cast<int>(std::lround(p.x())) + dx;
          const int j = static_cast<int>(std::lround(p.y())) + dy;
          const int k = static_cast<int>(std::lround(p.z())) + dz;
          if (i < 0 || j < 0 || k < 0 || i >= geometry_.dims.x() || j >= geometry_.dims.y() ||
              k >= geometry_.dims.z())
            continue;
          volume.at(i, j, k) = 250;
        }
  }
  // The moving disc.
  const double phase = 2.0 * std::numbers::pi * t;
  const Eigen::Vector3d disc =
      centre + Eigen::Vector3d(20 * std::cos(phase), 20 * std::sin(phase), dims.z() * 0.25);
  const int r = 12;
  for (int k = static_cast<int>(disc.z()) - 1; k <= static_cast<int>(disc.z()); ++k) {
    if (k < 0 || k >= geometry_.dims.z()) continue;
    for (int j = static_cast<int>(disc.y()) - r; j <= static_cast<int>(disc.y()) + r; ++j) {
      if (j < 0 || j >= geometry_.dims.y()) continue;
      for (int i = static_cast<int>(disc.x()) - r; i <= static_cast<int>(disc.x()) + r; ++i) {
        if (i < 0 || i >= geometry_.dims.x()) continue;
        const double di = i - disc.x(), dj = j - disc.y();
        if (di * di + dj * dj <= r * r) volume.at(i, j, k) = 200;
      }
    }
  }
  volume.set_timestamp_s(t);
  volume.set_frame_index(index_);

  FrameGroundTruth truth;
  truth.catheter_visible = true;
  truth.axis_point_mm = volume.IndexToPhysical(a);
  truth.axis_direction = (volume.IndexToPhysical(b) - volume.IndexToPhysical(a)).normalized();
  truth.tip_mm = volume.IndexToPhysical(b);
  truth.target_visible = true;
  truth.target_mm = volume.IndexToPhysical(disc);
  ++index_;
  return SourceFrame{std::move(volume), truth};
}

}  // namespace echoservo::imaging::openigtlink
