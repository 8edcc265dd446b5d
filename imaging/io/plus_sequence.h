// PLUS sequence metafiles (.igs.mha, .igs.nrrd): a stack of tracked ultrasound frames with
// per-frame fields, read and written by our own parser (no VTK).
//
// Frames: 2D (NDims 3), 3D volumes (NDims 4) or tracker-only (DimSize 0 0 N). Geometry in mm
// for one frame; frame fields kept as trimmed strings, with helpers for transforms (16
// numbers, row-major 4×4, mm; e.g. ImageToProbe, ProbeToReference), statuses and timestamps
// (s). A transform without a status counts as OK; NRRD's `Status` reads as `ImageStatus`.
// Sizes are checked before allocation (4 GiB cap, 2^20 frames, data present in the file).
// Errors: std::invalid_argument naming the file and the problem.
// Details: docs/imaging.md#plus-sequences-imagingioplus_sequenceh
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "imaging/volume.h"

namespace echoservo::imaging {

struct SequenceFrame {
  std::map<std::string, std::string> fields;  // name (without Seq_FrameNNNN_) → value

  std::optional<std::string> Field(const std::string& name) const;
  // `name` may be given with or without the "Transform" suffix (ProbeToTracker or
  // ProbeToTrackerTransform). nullopt when absent; throws naming the field when it is not
  // 16 finite numbers.
  std::optional<Eigen::Matrix4d> Transform(const std::string& name) const;
  // The status string of a transform ("OK", "INVALID", ...): the `<...>TransformStatus`
  // field, "OK" when the transform is present without one, nullopt when neither exists.
  std::optional<std::string> TransformStatus(const std::string& name) const;
  // Present and status OK.
  bool TransformValid(const std::string& name) const;
  // `Timestamp`, else `UnfilteredTimestamp`, in s; nullopt when neither; throws if malformed.
  std::optional<double> Timestamp() const;
  // `ImageStatus` (OK / INVALID), nullopt when absent.
  std::optional<std::string> ImageStatus() const;
};

struct PlusSequence {
  // Header fields other than the structural ones this struct owns (NDims, DimSize,
  // ElementType, geometry, compression, data file), in file order, e.g.
  // UltrasoundImageOrientation, Kinds, AnatomicalOrientation.
  std::vector<std::pair<std::string, std::string>> header_fields;
  std::array<int, 3> frame_dims = {0, 0, 0};  // X Y Z per frame (Z = 1 for 2D frames)
  bool volume_frames = false;                 // NDims = 4 (3D frames)
  std::string element_type = "MET_UCHAR";     // MetaImage spelling; MET_OTHER when no pixels
  int element_size = 1;                       // bytes per pixel
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones();
  Eigen::Vector3d origin_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();  // columns: index axes
  bool compressed = false;                                  // as read
  std::vector<SequenceFrame> frames;
  std::vector<std::uint8_t> pixels;  // all frames, frame after frame, x fastest

  std::uint64_t FrameBytes() const;  // X·Y·Z·element_size (0 when tracker-only)
  std::span<const std::uint8_t> FramePixels(std::size_t frame) const;
  std::span<std::uint8_t> FramePixels(std::size_t frame);
  // Names of all per-frame fields (union over frames), sorted.
  std::vector<std::string> FrameFieldNames() const;
  std::optional<std::string> HeaderField(const std::string& key) const;
};

// By content: NRRD magic → NRRD syntax, else MetaImage. The whole sequence, pixels included,
// is read into memory; imaging/io/sequence_reader.h reads one frame at a time.
PlusSequence ReadPlusSequence(const std::filesystem::path& path);

// Syntax by extension: .nrrd → NRRD (gzip when compress), otherwise MetaImage (.mha; zlib
// when compress). Frame numbers are written with 4 digits (more when needed), fields in
// name order. Throws std::invalid_argument when pixels.size() ≠ frames·FrameBytes().
void WritePlusSequence(const PlusSequence& sequence, const std::filesystem::path& path,
                       bool compress = true);

// Each frame as a Volume (MET_UCHAR only): geometry from the header, frame_index = frame
// number, timestamp from Timestamp/UnfilteredTimestamp (0 when absent), image_to_probe from
// `ImageToProbeTransform` and probe_to_reference from `ProbeToReferenceTransform` when
// present and OK (they must be rigid; identity otherwise).
std::vector<Volume> SequenceToVolumes(const PlusSequence& sequence);
Volume SequenceFrameToVolume(const PlusSequence& sequence, std::size_t frame);
// The same with the frame's pixels given (FrameBytes() of them; SequenceReader reads them
// from the file), `sequence.pixels` unused.
Volume SequenceFrameToVolume(const PlusSequence& sequence, std::size_t frame,
                             std::span<const std::uint8_t> pixels);
// The inverse: volumes with equal geometry → a NDims = 4 sequence (or NDims = 3 when every
// volume has dims.z = 1) with fields Timestamp, FrameNumber, ImageStatus = OK,
// ImageToProbeTransform(+Status), ProbeToReferenceTransform(+Status).
PlusSequence VolumesToSequence(std::span<const Volume> volumes);
// Its two halves, for writers that add frames one at a time (imaging/io/sequence_writer.h):
// the header of a sequence of volumes shaped like `first` (geometry, MET_UCHAR, no frames,
// no pixels), and the per-frame fields VolumesToSequence gives `volume`.
PlusSequence SequenceFor(const Volume& first);
SequenceFrame VolumeFrameFields(const Volume& volume);

// The MetaImage header (.mhd text, up to and including `ElementDataFile = <data_file_name>`)
// of `sequence`'s frames, whose raw, uncompressed pixels are in the file `data_file_name`
// beside the header; `sequence.pixels` is not used. Throws std::invalid_argument when the
// name is not a plain file name or a field cannot be written.
std::string PlusSequenceDetachedHeader(const PlusSequence& sequence,
                                       const std::string& data_file_name);

}  // namespace echoservo::imaging
