// Crash-safe recording of a volume stream as a PLUS sequence, one volume at a time.
//
// Role: `demo --save-volumes` and `track --save-volumes` record the volumes the tracker
// received while the run goes on, so that a process killed at any instant (kill -9, a
// crash) leaves a valid PLUS sequence of every volume whose Append returned — at most the
// volume in flight is lost — which `track --replay` and `report` read as they are.
//
// Layout (MetaImage with a detached data file, which PLUS and our reader take):
//   <name>.mhd  header: DimSize X Y Z N, geometry in mm, per-frame fields (FrameNumber,
//               Timestamp in s, ImageStatus, ImageToProbe/ProbeToReference transforms, and
//               any extra fields), `ElementDataFile = <name>.raw`;
//   <name>.raw  the N frames' voxels back to back, uint8, uncompressed.
// Each Append (1) appends the voxels to the .raw file in one write(2), then (2) writes the
// header listing one more frame to `<name>.mhd.tmp` and renames it over the header. A kill
// between the two leaves the previous header, which lists the frames before; readers
// ignore data past the frames a header lists.
//
// Cost: the header is rewritten whole each frame (≈ 0.6 kB per listed frame, e.g. 1 MB
// after a minute at 25 vol/s, against 4.9 MB of voxels per 160×148×208 frame).
// Errors: std::invalid_argument for a header path not ending in .mhd or a volume whose
// geometry differs from the first's (nothing is written for it); std::runtime_error naming
// the file on I/O errors, after which the writer refuses further frames (the data file's
// length is no longer known) while what was recorded before stays readable.
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
