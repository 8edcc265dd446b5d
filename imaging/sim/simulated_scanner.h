// SimulatedScanner: a VolumeSource that renders 3D ultrasound volumes of a water-tank scene
// (catheter sheath with a protruding metal guidewire, a moving saddle-shaped valve annulus,
// tank walls) by ray tracing a matrix-array probe's beams (Embree) and modelling the echoes.
//
// Units: mm, s, rad, m/s, dB. Frames: world = the tank's; ProbeToWorld; CatheterBaseToWorld
// (+z along the axis to the tip; advances by advance_mm, the plant's tip_mm); AnnulusToWorld
// (+z its normal, along which the target motion displaces it). Volumes and ground truth are
// in the image frame = displayed probe frame (true distances × assumed / medium sound speed).
// Errors: options are validated (std::invalid_argument naming the field).
// Details: docs/simulated_scanner.md#frames-mm-s-rad
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "imaging/sim/probe.h"
#include "imaging/sim/scene.h"
#include "imaging/volume_source.h"

namespace echoservo::imaging::sim {

struct CatheterGeometry {
  double sheath_diameter_mm = 2.5;  // outer diameter, (0, 20]
  double sheath_length_mm = 40.0;   // modelled length from the base, (0, 1000]
  double wire_diameter_mm = 0.9;    // (0, sheath_diameter)
  double wire_protrusion_mm = 8.0;  // beyond the sheath end, [0, 200]
};

struct AnnulusGeometry {
  double diameter_mm = 28.0;  // (0, 100]
  double thickness_mm = 3.0;  // (0, 20]
  double saddle_mm = 2.0;     // saddle height, |·| < diameter
};

// Default poses: probe at the world origin looking down +z; catheter entering the field of
// view from −x at 60 mm depth, tilted 10° towards depth; annulus centred on the catheter
// axis 15 mm beyond the guidewire tip (at advance 0), facing the catheter.
Eigen::Isometry3d DefaultCatheterBaseToWorld();
Eigen::Isometry3d DefaultAnnulusToWorld();

struct CatheterPose {
  Eigen::Isometry3d base_to_world = DefaultCatheterBaseToWorld();
  double advance_mm = 0.0;  // along the catheter axis (+z of the base frame)
};

struct SimulatedScannerOptions {
  double rate_hz = 25.0;         // volumes per second, (0, 200]
  double start_time_s = 0.0;     // timestamp of frame 0, finite
  std::int64_t max_frames = -1;  // end of stream after this many; −1: endless
  ProbeGeometry probe;
  Eigen::Isometry3d probe_to_world = Eigen::Isometry3d::Identity();

  double medium_sound_speed_m_s = 1482.0;   // water at 20 °C, [1000, 2000]
  double assumed_sound_speed_m_s = 1540.0;  // the scanner's, [1000, 2000]
  double frequency_mhz = 3.0;               // (0, 20]
  double attenuation_db_cm_mhz = 0.5;       // medium, round trip per one-way cm, [0, 5]
  double tgc_db_cm_mhz = 0.5;               // time-gain compensation slope, [0, 5]
  double gain_db = 0.0;                     // [−60, 60]
  double dynamic_range_db = 50.0;           // log compression window, [10, 120]
  double axial_psf_mm = 0.3;                // Gaussian σ of the pulse envelope, (0, 5]
  double lateral_psf_beams = 0.7;           // σ across azimuth, in beams, (0, 4]
  double elevation_psf_beams = 1.2;         // σ across elevation, in beams, (0, 4]
  double background_scatter = 0.004;        // weak scatterers in water, [0, 1]
  double noise_floor = 0.002;               // electronic noise after TGC, [0, 1]
  std::uint64_t seed = 1;

  bool catheter = true;  // false: catheter-free scene (false-detection tests)
  bool annulus = true;
  bool tank = true;
  bool reverberation = true;
  CatheterGeometry catheter_geometry;
  AnnulusGeometry annulus_geometry;
  CatheterPose catheter_pose;  // initial pose
  Eigen::Isometry3d annulus_to_world = DefaultAnnulusToWorld();
  Eigen::Vector3d tank_min_mm{-90.0, -70.0, -10.0};
  Eigen::Vector3d tank_max_mm{90.0, 70.0, 105.0};
  // Optional: catheter pose and annulus displacement (mm along its normal) at time t (s),
  // evaluated at each frame's timestamp. Null: the last SetCatheterPose / 0 mm.
  std::function<CatheterPose(double)> catheter_pose_at;
  std::function<double(double)> target_displacement_mm;
  // Extra static meshes in the world frame.
  struct ExtraMesh {
    TriangleMesh mesh;
    AcousticProperties properties;
    Eigen::Isometry3d mesh_to_world = Eigen::Isometry3d::Identity();
  };
  std::vector<ExtraMesh> extra_meshes;

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

class SimulatedScanner final : public VolumeSource {
 public:
  explicit SimulatedScanner(SimulatedScannerOptions options);
  ~SimulatedScanner() override;

  std::optional<SourceFrame> Next() override;
  double nominal_rate_hz() const override { return options_.rate_hz; }

  // Used when no catheter_pose_at callback is set. Throws for a non-finite pose.
  void SetCatheterPose(const CatheterPose& pose);
  const SimulatedScannerOptions& options() const { return options_; }
  const ProbeGeometry& probe() const { return options_.probe; }
  // Displayed/true range ratio: assumed / medium speed of sound.
  double depth_scale() const {
    return options_.assumed_sound_speed_m_s / options_.medium_sound_speed_m_s;
  }
  // World point (true, mm) → image frame (displayed probe frame, mm).
  Eigen::Vector3d WorldToImage(const Eigen::Vector3d& world_mm) const;
  // The polar image of the last frame (uint8, azimuth fastest; see ProbeGeometry::PolarIndex).
  std::span<const std::uint8_t> last_polar() const;
  // Renders the frame at time t without advancing the stream (frame index 0).
  SourceFrame Render(double t_s);

 private:
  struct Impl;
  SimulatedScannerOptions options_;
  std::unique_ptr<Impl> impl_;
  std::int64_t next_frame_ = 0;
};

}  // namespace echoservo::imaging::sim
