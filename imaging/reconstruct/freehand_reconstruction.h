// Freehand 3D reconstruction: a tracked sweep of 2D ultrasound frames (a PLUS sequence) →
// one 3D volume, the way PLUS's vtkPlusVolumeReconstructor does it.
//
// Frames: each frame's pixel (i, j) is the point (i, j, 0) of the Image frame (pixel units,
// PLUS's convention: the calibration carries the mm/pixel scale, the sequence's
// ElementSpacing is not used). It is placed in the output frame by
// ImageToProbe · ProbeToTracker (· TrackerToReference, the inverse of the reference tool's
// `<Ref>ToTracker`, when a reference tool is named). ImageToProbe is affine (rotation ·
// scale, mm per pixel), the tracker transforms rigid, in mm. The output volume is
// axis-aligned in the tracker (or reference) frame, in mm; its extent is the bounding box of
// the used frames' corner pixels or a given region of interest.
// Compounding: nearest voxel (last value or mean) or distance-weighted (each pixel splatted
// into its 2×2×2 neighbouring voxels with trilinear weights, normalised at the end); then
// optional hole filling (an empty voxel takes the Gaussian-weighted mean of the known voxels
// within a (2r+1)³ kernel when at least `hole_fill_min_known_ratio` of them are known).
// Bad frames (missing, non-OK, non-finite or non-rigid tracker transforms; ImageStatus not
// OK) are skipped and counted by reason. Memory: about 10 bytes per output voxel while running.
// Errors: std::invalid_argument naming the problem for a sequence that cannot be
// reconstructed (3D or tracker-only frames, an element type other than MET_UCHAR, no
// calibration, a singular or non-finite calibration, no usable frame, bad options) and for a
// region larger than `max_voxels` (the numbers are in the message).
// Details: docs/reconstruction.md
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "imaging/io/plus_sequence.h"
#include "imaging/volume.h"

namespace echoservo::imaging {

enum class Compounding {
  kNearestLast,  // nearest voxel, the last frame's pixel wins
  kNearestMean,  // nearest voxel, mean of the pixels that fell in it
  kWeighted,     // trilinear splat into the 8 voxels around the pixel, weighted mean
};

struct ReconstructionOptions {
  double spacing_mm = 0.5;                    // isotropic output voxel pitch, > 0
  std::optional<Eigen::AlignedBox3d> roi_mm;  // output region (output frame); else the sweep's
  // Image → probe (16 numbers, mm per pixel scale included). When absent: the frame field
  // `ImageToProbeTransform` (per frame, status OK), else the header field
  // `ImageToProbeTransform` (or `ImageToProbe`); neither is an error.
  std::optional<Eigen::Matrix4d> image_to_probe;
  std::string probe_tool = "Probe";  // frames' `<probe_tool>ToTrackerTransform`
  std::string reference_tool;        // empty: output in the tracker frame
  Compounding compounding = Compounding::kWeighted;
  bool fill_holes = true;
  int hole_fill_radius_voxels = 1;              // kernel (2r+1)³, r in [1, 5]
  double hole_fill_min_known_ratio = 0.5;       // in (0, 1]
  std::int64_t max_voxels = 512LL * 512 * 512;  // refused above this, before allocation
  // Called after each frame with (frames done, frames total); may be empty.
  std::function<void(std::size_t, std::size_t)> progress;
};

struct ReconstructionResult {
  Volume volume;  // uint8, in the output frame; identity poses (no beam geometry)
  std::size_t frames_total = 0;
  std::size_t frames_used = 0;
  std::size_t skipped_image_status = 0;       // ImageStatus present and not OK
  std::size_t skipped_missing_transform = 0;  // probe/reference/calibration field absent
  std::size_t skipped_invalid_status = 0;     // a needed transform's status not OK
  std::size_t skipped_bad_transform = 0;      // unparsable, non-finite or not rigid
  std::size_t FramesSkipped() const {
    return skipped_image_status + skipped_missing_transform + skipped_invalid_status +
           skipped_bad_transform;
  }
  std::int64_t pixels_outside = 0;       // pixels that fell outside the output region
  std::int64_t voxels_known = 0;         // voxels hit by at least one pixel
  std::int64_t voxels_filled_holes = 0;  // voxels set by hole filling
  std::string calibration_source;        // "option", "frame field", "header field"
  Eigen::Matrix4d image_to_probe = Eigen::Matrix4d::Identity();  // first used frame's
  std::string output_frame;  // "Tracker" or the reference tool's name
};

// Throws std::invalid_argument as described in the header comment.
ReconstructionResult ReconstructFreehand(const PlusSequence& sequence,
                                         const ReconstructionOptions& options = {});

// Checks an image-to-probe calibration: 16 finite numbers, last row 0 0 0 1, linear part
// invertible (|det| > 1e-12). Throws std::invalid_argument naming `where` and the problem.
void ValidateImageToProbe(const Eigen::Matrix4d& image_to_probe, const std::string& where);

// How well two volumes in the same frame agree: Pearson correlation of their trilinear
// samples over the overlap where both are non-zero (samples at `a`'s voxel centres), and the
// integer voxel shift of `b` within ±max_shift_voxels (along each axis, in a's voxel pitch)
// that maximises that correlation.
struct VolumeAgreement {
  std::int64_t overlap_voxels = 0;                          // at zero shift
  double correlation = 0.0;                                 // at zero shift
  Eigen::Vector3d best_shift_mm = Eigen::Vector3d::Zero();  // b sampled at x + shift
  double best_correlation = 0.0;
};
VolumeAgreement CompareVolumes(const Volume& a, const Volume& b, int max_shift_voxels = 4);

}  // namespace echoservo::imaging
