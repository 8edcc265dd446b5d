// The volume classes of the detector accuracy harness (tracking/detector_accuracy.h): simulated
// 3D ultrasound volumes (imaging/sim/simulated_scanner.h) with their ground truth, plus the
// real catheter-free phantom volume.
//
// Each class is a scene recipe; volume `index` of a class draws its catheter pose (yaw about
// the probe axis, tilt towards depth, tip depth, lateral offset, advance) and speckle seed from
// a seeded RNG, so the same (class, index, seed) always gives the same volume. Catheter poses
// follow the convention of tests/tracking/radon_detector_test.cc: the base frame's +z is the
// catheter axis, the guidewire tip (48 mm from the base at advance 0) at (lateral, 0, depth)
// in the world (tank) frame, the annulus centred on the axis 15 mm beyond it.
//
// Units: mm, deg in the descriptions, m/s; truth in the volume's image frame (mm).
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "imaging/ground_truth.h"
#include "imaging/volume.h"

namespace echoservo::tracking {

struct VolumeClass {
  std::string name;
  std::string description;
  bool catheter = true;  // false: catheter-free (every detection is a false detection)
  bool real = false;     // true: the real phantom volume (one volume, whatever the count)
};

// All classes, in report order: water_tank (the default scene, moderate poses), no_reverberation,
// speckle_clutter, shadowing, wide_poses, sound_speed, then the catheter-free free_annulus,
// free_tank, free_clutter and spine_phantom; then the independent generator's
// (tracking/independent_volumes.h) beam_00 … beam_80 (catheter at that angle to the beam, comet
// tails, the volume knows its beams), beam_00_unknown … beam_80_unknown (it does not) and the
// catheter-free indep_free; deep_50, deep_56, deep_60, deep_70, deep_80 (that angle to the beam,
// the tip 80–100 mm deep, specular fall-off with obliquity, attenuation and TGC, noise, lateral
// PSF widening with depth; known beams) and the catheter-free deep_free.
const std::vector<VolumeClass>& VolumeClasses();
// Throws std::invalid_argument listing the known names.
const VolumeClass& FindVolumeClass(const std::string& name);

struct AccuracyVolume {
  imaging::Volume volume;
  std::optional<imaging::FrameGroundTruth> truth;  // simulated classes only
  // Catheter classes with a next frame: the same scene with the catheter advanced by 1 mm
  // (for tracking mode, searched near the first frame's axis).
  std::optional<imaging::Volume> next_volume;
  std::optional<imaging::FrameGroundTruth> next_truth;
  std::string label;  // the drawn parameters, for logs
};

// Volume `index` of class `cls`. `spine_volume` is the real volume's file (spine_phantom only).
// Throws std::invalid_argument when spine_phantom's file is missing or unreadable.
AccuracyVolume MakeAccuracyVolume(const VolumeClass& cls, int index, std::uint64_t seed,
                                  bool next_frame, const std::filesystem::path& spine_volume);

}  // namespace echoservo::tracking
