// A second, independent generator of 3D ultrasound volumes with a catheter, sharing no code
// with the simulated scanner (imaging/sim): it renders the image directly, not by ray tracing
// and beam forming, so the detector is tested on images it was not tuned on.
//
// The scene, in a beam-aligned grid (index k along the beam for parallel beams; beams from an
// apex above the grid's centre otherwise): Rayleigh speckle (a complex Gaussian field smoothed
// by an anisotropic Gaussian point-spread function, axial_psf_mm along the beam, lateral_psf_mm
// across it) of blood and of a tissue half-space whose surface lies target_gap_mm ahead of the
// tip, ⟂ the catheter; a catheter (a sheath of sheath_diameter_mm and a guidewire of
// wire_diameter_mm protruding wire_protrusion_mm) imaged at its near walls (radius towards the
// transducer), each a line blurred analytically by the PSF; reverberation comet tails (copies of
// those echoes displaced along the beam every reverb_spacing_mm, amplitude × reverb_decay each);
// a shadow behind the catheter. Values are log-compressed to 0–255 over dynamic_range_db.
// Depth and obliquity (all off by default): round-trip attenuation and time-gain compensation
// by range from the apex, receiver noise amplified by the TGC, the sheath's and the wire's
// specular echo falling off with the angle of incidence (to a rough, diffuse part), and a
// lateral PSF widening beyond a focal range.
// The grid's direction matrix is a rotation taking the grid's beam axis to `beam_direction`.
// Units: mm, deg; truth in the volume's image frame (mm).
// Errors: Validate (called by MakeIndependentVolume) throws std::invalid_argument naming the
// field.
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "imaging/ground_truth.h"
#include "imaging/volume.h"

namespace echoservo::tracking {

struct IndependentVolumeOptions {
  int size_voxels = 96;             // cube side, [32, 256]
  double voxel_mm = 0.5;            // (0, 2]
  double catheter_angle_deg = 40;   // angle between the catheter axis and the beam, [0, 90]
  double catheter_azimuth_deg = 0;  // direction of the catheter's lateral part about the beam
  // true: the tip points towards the transducer (the shaft and its comet tails deeper); false:
  // away from it (the wire's comet tail then runs on beyond the tip).
  bool tip_towards_probe = true;
  Eigen::Vector3d tip_offset_mm = Eigen::Vector3d::Zero();  // tip from the grid centre (grid frame)
  double advance_mm = 0;         // the tip moved this far along the catheter (the next frame)
  bool catheter = true;          // false: tissue and blood only (truth.catheter_visible = false)
  bool parallel_beam = false;    // true: a linear probe; false: beams from an apex
  double apex_distance_mm = 40;  // apex above the grid's top face (pyramidal scan), > 0
  Eigen::Vector3d beam_direction = Eigen::Vector3d::UnitZ();  // the grid's beam axis, image frame
  bool store_image_to_probe = true;  // the volume says where its beams come from
  double sheath_diameter_mm = 2.5;
  double wire_diameter_mm = 0.9;
  double wire_protrusion_mm = 8;
  double sheath_amplitude = 1.0;  // echo amplitudes relative to the display's top
  double wire_amplitude = 0.8;
  double far_wall_amplitude = 0.15;  // the sheath's far wall (behind, weaker)
  double axial_psf_mm = 0.3;         // Gaussian σ along the beam
  double lateral_psf_mm = 0.6;       // Gaussian σ across it
  double reverb_spacing_mm = 2.5;    // ~ the tube's diameter
  double reverb_decay = 0.5;         // amplitude ratio of successive copies, [0, 1)
  int reverb_copies = 4;             // 0: no comet tail
  double shadow = 0.3;               // speckle amplitude factor behind the catheter, [0, 1]
  double blood_scatter = 0.004;      // mean speckle amplitude of blood
  double tissue_scatter = 0.04;      // of the tissue ahead
  double target_gap_mm = 5;          // tissue surface ahead of the tip, > 0
  double dynamic_range_db = 50;
  // Depth (range r: distance from the apex; parallel beams: apex_distance_mm + depth in the
  // grid). Every echo and the speckle × 10^((tgc − attenuation)·(r − gain_reference_mm)/20);
  // receiver noise (complex Gaussian of σ noise_amplitude per component, white) ×
  // 10^(tgc·(r − gain_reference_mm)/20): with full compensation the echoes keep their level
  // and the noise rises with depth; without, they sink towards the noise and the display floor.
  double attenuation_db_per_mm = 0;  // round trip, [0, 2)
  double tgc_db_per_mm = 0;          // [0, 2)
  double gain_reference_mm = 60;     // (0, 1000)
  double noise_amplitude = 0;        // [0, 1)
  // Obliquity: a smooth wall reflects back along the beam only near normal incidence. The
  // sheath's walls (and their comet tails) × diffuse + (1 − diffuse)·exp(−½(ψ/width)²), ψ the
  // angle between the beam and the wall's normal (90° − the catheter's angle to the beam);
  // the same for the wire with its own width and diffuse part. Width 0: no fall-off.
  double specular_width_deg = 0;  // [0, 90]
  double specular_diffuse = 0.1;  // [0, 1]
  double wire_specular_width_deg = 0;
  double wire_specular_diffuse = 0.3;
  // Lateral PSF beyond the focus: σ = lateral_psf_mm · max(1, r / lateral_focus_mm) (the
  // beam diverges; a line keeps its peak over the speckle, which widens with it); 0: constant.
  double lateral_focus_mm = 0;  // 0 or (0, 1000)
  std::uint64_t seed = 1;

  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

struct IndependentVolume {
  imaging::Volume volume;
  imaging::FrameGroundTruth truth;  // axis through the sheath's centre line, tip, target
  Eigen::Vector3d beam_at_tip = Eigen::Vector3d::UnitZ();  // image frame, unit
};

IndependentVolume MakeIndependentVolume(const IndependentVolumeOptions& options);

// Issue 32's depth and obliquity physics: the sheath's specular echo falls off with the angle of
// incidence (width 10°) to a diffuse part of 0.15 (−16.5 dB), the guidewire's (width 20°) to
// 0.3 (−10.5 dB); round-trip attenuation 0.3 dB/mm under a TGC of 0.25 dB/mm (reference 60 mm),
// receiver noise 0.002 amplified by the TGC, the lateral PSF widening beyond 60 mm.
void SetDeepObliquePhysics(IndependentVolumeOptions& options);
// Sets apex_distance_mm so that the tip lies depth_mm from the apex (its range), the grid and
// tip_offset_mm as they are. Throws std::invalid_argument when the grid would have to start
// above the apex.
void PlaceTipAtDepth(IndependentVolumeOptions& options, double depth_mm);

}  // namespace echoservo::tracking
