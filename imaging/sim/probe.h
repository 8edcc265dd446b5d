// Matrix-array probe of the simulated scanner: a pyramidal field of view sampled by a grid
// of beams, and the scan conversion of the polar (beam × range-sample) image into a
// Cartesian Volume.
//
// Units: mm, rad. Probe frame: origin at the array centre (the pyramid's apex), +z along the
// central beam (depth), +x azimuth, +y elevation. Ranges are *displayed* ranges (echo time ×
// the scanner's assumed sound speed). The volumes' image frame is the displayed probe frame
// (image_to_probe = identity). Polar buffers are uint8, azimuth fastest (PolarIndex).
// Errors: Validate throws std::invalid_argument naming the field.
// Details: docs/simulated_scanner.md#frames-mm-s-rad
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "imaging/volume.h"

namespace echoservo::imaging::sim {

struct ProbeGeometry {
  double azimuth_rad = 60.0 * 3.14159265358979323846 / 180.0;    // (0, 170°]
  double elevation_rad = 30.0 * 3.14159265358979323846 / 180.0;  // (0, 170°]
  double range_mm = 120.0;                                       // displayed depth, (0, 500]
  int n_azimuth = 128;                                           // [2, 1024]
  int n_elevation = 64;                                          // [2, 1024]
  int n_samples = 512;                                           // [8, 8192]
  Eigen::Vector3i volume_dims{160, 148, 208};                    // voxels x, y, z

  // Throws std::invalid_argument naming the field (prefixed by `where`).
  void Validate(const std::string& where = "probe geometry") const;

  std::size_t PolarIndex(int ia, int ie, int s) const {
    return (static_cast<std::size_t>(ie) * static_cast<std::size_t>(n_samples) +
            static_cast<std::size_t>(s)) *
               static_cast<std::size_t>(n_azimuth) +
           static_cast<std::size_t>(ia);
  }
  int beam_count() const { return n_azimuth * n_elevation; }
  std::size_t polar_size() const {
    return static_cast<std::size_t>(beam_count()) * static_cast<std::size_t>(n_samples);
  }
  double sample_spacing_mm() const { return range_mm / (n_samples - 1); }
  double AzimuthOf(int ia) const { return -0.5 * azimuth_rad + ia * azimuth_rad / (n_azimuth - 1); }
  double ElevationOf(int ie) const {
    return -0.5 * elevation_rad + ie * elevation_rad / (n_elevation - 1);
  }
  Eigen::Vector3d BeamDirection(int ia, int ie) const;
  // Displayed probe-frame point → continuous (ia, ie, s); false outside the pyramid.
  bool ToPolar(const Eigen::Vector3d& p_mm, Eigen::Vector3d* polar) const;
  // The volume grid spanning the pyramid (image frame = displayed probe frame).
  VolumeGeometry MakeVolumeGeometry() const;
};

// Precomputed voxel → polar lookup (8-bit trilinear weights), applied in parallel (TBB).
class ScanConverter {
 public:
  explicit ScanConverter(const ProbeGeometry& probe);
  const VolumeGeometry& geometry() const { return geometry_; }
  // `polar` has probe.polar_size() samples; `volume` has geometry(). Voxels outside the
  // pyramid are set to 0.
  void Convert(std::span<const std::uint8_t> polar, Volume& volume) const;

 private:
  struct Entry {
    std::uint32_t base;  // polar index of the (ia, ie, s) corner
    std::uint8_t wa, we, ws, pad;
  };
  struct Run {            // consecutive inside voxels of one x row
    std::uint32_t voxel;  // linear index of the first
    std::uint32_t length;
    std::uint32_t entry;  // index of its first Entry
  };
  ProbeGeometry probe_;
  VolumeGeometry geometry_;
  std::vector<Entry> lut_;  // inside voxels only, in voxel order
  std::vector<Run> runs_;
  std::vector<std::uint32_t> row_runs_;  // runs of x row r: [row_runs_[r], row_runs_[r + 1])
};

}  // namespace echoservo::imaging::sim
