// Crash-safe recording of a volume stream as a PLUS sequence, one volume at a time
// (`demo --save-volumes`, `track --save-volumes`; read back by `track --replay`, `report`).
//
// Writes <name>.mhd (header: geometry in mm, per-frame FrameNumber, Timestamp in s,
// ImageStatus, ImageToProbe/ProbeToReference transforms, extra fields) and <name>.raw (uint8
// voxels). A process killed at any instant leaves a valid sequence of every volume whose
// Append returned. Errors: std::invalid_argument for a header path not ending in .mhd or a
// volume whose geometry differs from the first's (nothing written); std::runtime_error
// naming the file on I/O errors, after which further frames are refused (what was recorded
// before stays readable).
// Details: docs/imaging.md#recording-volumes-imagingiosequence_writerh
#pragma once

#include <cstddef>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "imaging/volume.h"

namespace echoservo::imaging {

class SequenceWriter {
 public:
  // Files are created with the first Append (truncating existing ones).
  explicit SequenceWriter(std::filesystem::path header_path);
  ~SequenceWriter();
  SequenceWriter(const SequenceWriter&) = delete;
  SequenceWriter& operator=(const SequenceWriter&) = delete;

  // Records `volume` with VolumeFrameFields(volume) plus `extra_fields` (e.g. ground truth).
  void Append(const Volume& volume, const std::map<std::string, std::string>& extra_fields = {});
  // fdatasync of the voxel file (the header is replaced whole on every Append).
  void SyncData();

  std::size_t frames() const;
  const std::filesystem::path& header_path() const { return header_path_; }
  std::filesystem::path data_path() const;

 private:
  struct State;
  std::filesystem::path header_path_;
  std::unique_ptr<State> state_;
};

}  // namespace echoservo::imaging
