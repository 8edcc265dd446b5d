// Reading a PLUS sequence one frame at a time, for replaying long recordings (OpenRecording,
// `track --replay`): memory holds one frame, not the whole sequence.
//
// Uncompressed data is streamed from the file (the sequence may exceed 4 GiB; each frame
// within 4 GiB); compressed data is inflated whole at open, within the 4 GiB cap.
// Units and frames as in plus_sequence.h (mm, s; ImageToProbe, ProbeToReference).
// Errors: std::invalid_argument naming the file: at open as ReadPlusSequence; from ReadVolume
// for a frame out of range, an element type other than MET_UCHAR, or a data file that has
// shrunk since it was opened.
// Details: docs/imaging.md#reading-long-sequences-imagingiosequence_readerh
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "imaging/io/plus_sequence.h"
#include "imaging/volume.h"

namespace echoservo::imaging {

class SequenceReader {
 public:
  explicit SequenceReader(const std::filesystem::path& path);
  ~SequenceReader();
  SequenceReader(const SequenceReader&) = delete;
  SequenceReader& operator=(const SequenceReader&) = delete;

  // Header, geometry and frame fields; `pixels` is empty when streamed.
  const PlusSequence& sequence() const { return sequence_; }
  std::size_t size() const { return sequence_.frames.size(); }
  // True when frames are read from the file on demand (uncompressed data).
  bool streamed() const { return fd_ >= 0; }
  const std::filesystem::path& path() const { return path_; }

  // Frame `frame` as SequenceFrameToVolume gives it.
  Volume ReadVolume(std::size_t frame);

 private:
  std::filesystem::path path_;
  PlusSequence sequence_;
  std::filesystem::path data_path_;
  std::uint64_t data_offset_ = 0;
  int fd_ = -1;
  std::vector<std::uint8_t> buffer_;  // one frame
};

}  // namespace echoservo::imaging
