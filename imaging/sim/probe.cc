#include "imaging/sim/probe.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace echoservo::imaging::sim {
namespace {

void RequireProbeRange(double v, double lo, double hi, const std::string& where,
                       const std::string& field, bool open_low = false) {
  if (!(std::isfinite(v) && (open_low ? v > lo : v >= lo) && v <= hi)) {
    std::ostringstream os;
    os << where << ": " << field << " must be in " << (open_low ? "(" : "[") << lo << ", " << hi
       << "], got " << v;
    throw std::invalid_argument(os.str());
  }
}

}  // namespace

void ProbeGeometry::Validate(const std::string& where) const {
  const double max_angle = 170.0 * std::numbers::pi / 180.0;
  RequireProbeRange(azimuth_rad, 0.0, max_angle, where, "azimuth_rad", true);
  RequireProbeRange(elevation_rad, 0.0, max_angle, where, "elevation_rad", true);
  RequireProbeRange(range_mm, 0.0, 500.0, where, "range_mm", true);
  RequireProbeRange(n_azimuth, 2, 1024, where, "n_azimuth");
  RequireProbeRange(n_elevation, 2, 1024, where, "n_elevation");
  RequireProbeRange(n_samples, 8, 8192, where, "n_samples");
  MakeVolumeGeometry().Validate(where + " volume_dims");
}

Eigen::Vector3d ProbeGeometry::BeamDirection(int ia, int ie) const {
  const double az = AzimuthOf(ia), el = ElevationOf(ie);
  return {std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el)};
}

bool ProbeGeometry::ToPolar(const Eigen::Vector3d& p, Eigen::Vector3d* polar) const {
  const double r = p.norm();
  if (!(r <= range_mm) || r <= 0.0) return false;
  const double el = std::asin(std::clamp(p.y() / r, -1.0, 1.0));
  const double az = std::atan2(p.x(), p.z());
  const double ia = (az + 0.5 * azimuth_rad) / azimuth_rad * (n_azimuth - 1);
  const double ie = (el + 0.5 * elevation_rad) / elevation_rad * (n_elevation - 1);
  if (ia < 0 || ia > n_azimuth - 1 || ie < 0 || ie > n_elevation - 1) return false;
  *polar = {ia, ie, r / sample_spacing_mm()};
  return true;
}

VolumeGeometry ProbeGeometry::MakeVolumeGeometry() const {
  VolumeGeometry g;
  g.dims = volume_dims;
  const double half_az = 0.5 * azimuth_rad, half_el = 0.5 * elevation_rad;
  const double x_max = range_mm * std::sin(std::min(half_az, std::numbers::pi / 2));
  const double y_max = range_mm * std::sin(std::min(half_el, std::numbers::pi / 2));
  // Shallowest depth of the pyramid: the apex, or below it for angles beyond 90°.
  const double z_min = std::min(0.0, range_mm * std::cos(half_az) * std::cos(half_el));
  const Eigen::Vector3d lo(-x_max, -y_max, z_min), hi(x_max, y_max, range_mm);
  for (int a = 0; a < 3; ++a) {
    const int n = std::max(2, volume_dims[a]);
    g.spacing_mm[a] = (hi[a] - lo[a]) / (n - 1);
  }
  g.origin_mm = lo;
  return g;
}

ScanConverter::ScanConverter(const ProbeGeometry& probe)
    : probe_(probe), geometry_(probe.MakeVolumeGeometry()) {
  probe.Validate("ScanConverter probe");
  const auto& d = geometry_.dims;
  const int rows = d.y() * d.z();
  // Pass 1 (parallel): the entries of every row; pass 2: concatenate.
  std::vector<std::vector<Entry>> row_entries(static_cast<std::size_t>(rows));
  std::vector<std::vector<Run>> row_run_list(static_cast<std::size_t>(rows));
  tbb::parallel_for(0, rows, [&](int row) {
    const int j = row % d.y(), k = row / d.y();
    auto& entries = row_entries[static_cast<std::size_t>(row)];
    auto& runs = row_run_list[static_cast<std::size_t>(row)];
    bool in_run = false;
    for (int i = 0; i < d.x(); ++i) {
      const Eigen::Vector3d p =
          geometry_.origin_mm + Eigen::Vector3d(i, j, k).cwiseProduct(geometry_.spacing_mm);
      Eigen::Vector3d q;
      if (!probe.ToPolar(p, &q)) {
        in_run = false;
        continue;
      }
      const double ia = std::min(q.x(), probe.n_azimuth - 1.000001);
      const double ie = std::min(q.y(), probe.n_elevation - 1.000001);
      const double s = std::min(q.z(), probe.n_samples - 1.000001);
      const int a0 = static_cast<int>(ia), e0 = static_cast<int>(ie), s0 = static_cast<int>(s);
      auto w8 = [](double f) {
        return static_cast<std::uint8_t>(std::min(255.0, std::round(f * 256.0)));
      };
      const std::uint32_t voxel = static_cast<std::uint32_t>(i + d.x() * row);
      if (!in_run) runs.push_back({voxel, 0, static_cast<std::uint32_t>(entries.size())});
      in_run = true;
      ++runs.back().length;
      entries.push_back({static_cast<std::uint32_t>(probe.PolarIndex(a0, e0, s0)), w8(ia - a0),
                         w8(ie - e0), w8(s - s0), 0});
    }
  });
  row_runs_.push_back(0);
  for (int row = 0; row < rows; ++row) {
    const auto offset = static_cast<std::uint32_t>(lut_.size());
    for (Run r : row_run_list[static_cast<std::size_t>(row)]) {
      r.entry += offset;
      runs_.push_back(r);
    }
    row_runs_.push_back(static_cast<std::uint32_t>(runs_.size()));
    lut_.insert(lut_.end(), row_entries[static_cast<std::size_t>(row)].begin(),
                row_entries[static_cast<std::size_t>(row)].end());
  }
}

void ScanConverter::Convert(std::span<const std::uint8_t> polar, Volume& volume) const {
  if (polar.size() != probe_.polar_size())
    throw std::invalid_argument("ScanConverter::Convert: polar size mismatch");
  if (volume.dims() != geometry_.dims)
    throw std::invalid_argument("ScanConverter::Convert: volume dims mismatch");
  const std::uint8_t* src = polar.data();
  std::uint8_t* dst = volume.voxels().data();
  const std::size_t nx = static_cast<std::size_t>(geometry_.dims.x());
  const std::size_t da = 1;
  const std::size_t ds = static_cast<std::size_t>(probe_.n_azimuth);
  const std::size_t de = static_cast<std::size_t>(probe_.n_samples) * ds;
  const int rows = static_cast<int>(row_runs_.size()) - 1;
  tbb::parallel_for(tbb::blocked_range<int>(0, rows, 16), [&](const tbb::blocked_range<int>& rr) {
    for (int row = rr.begin(); row != rr.end(); ++row) {
      std::uint8_t* out = dst + static_cast<std::size_t>(row) * nx;
      std::memset(out, 0, nx);
      for (std::uint32_t ri = row_runs_[static_cast<std::size_t>(row)];
           ri < row_runs_[static_cast<std::size_t>(row) + 1]; ++ri) {
        const Run run = runs_[ri];
        const Entry* e = lut_.data() + run.entry;
        std::uint8_t* o = dst + run.voxel;
        for (std::uint32_t v = 0; v < run.length; ++v) {
          const std::uint8_t* p = src + e[v].base;
          const int ws = e[v].ws, wa = e[v].wa, we = e[v].we;
          auto lerp_a = [&](const std::uint8_t* q) {
            return (q[0] << 8) + (q[da] - q[0]) * wa;
          };  // ×256
          const int c00 = lerp_a(p), c10 = lerp_a(p + ds), c01 = lerp_a(p + de),
                    c11 = lerp_a(p + de + ds);
          const int c0 = (c00 << 8) + (c10 - c00) * ws;  // ×65536
          const int c1 = (c01 << 8) + (c11 - c01) * ws;
          const int c = ((c0 + 128) >> 8) * 256 + ((c1 - c0) >> 8) * we;  // ×65536
          o[v] = static_cast<std::uint8_t>(std::clamp((c + 32768) >> 16, 0, 255));
        }
      }
    }
  });
}

}  // namespace echoservo::imaging::sim
