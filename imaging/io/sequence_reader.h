// Reading a PLUS sequence one frame at a time, for replaying long recordings.
//
// Role: OpenRecording (and so `track --replay`) takes a sequence's volumes in order.
// ReadPlusSequence holds the whole sequence in memory within a 4 GiB cap: about 35 s of
// 4.9 MB volumes at 25 vol/s. SequenceReader parses the header and every frame's fields when
// it opens (the same checks and errors as ReadPlusSequence), then reads a frame's pixels from
// the file when that frame is asked for, so memory holds one frame.
//
// Uncompressed pixel data (after the header with `ElementDataFile = LOCAL`, or a detached
// data file such as SequenceWriter's .raw) is streamed: the sequence may exceed 4 GiB, as long
// as the file holds all the frames the header declares (checked at open) and each frame is
// within 4 GiB. Compressed data is one zlib/gzip stream that cannot be entered mid-way: it is
// inflated whole when the reader opens, within the 4 GiB cap, as ReadPlusSequence does.
//
// Units and frames as in plus_sequence.h (mm, s; ImageToProbe, ProbeToReference).
// Errors: std::invalid_argument naming the file: at open as ReadPlusSequence; from ReadVolume
// for a frame out of range, an element type other than MET_UCHAR, or a data file that has
// shrunk since it was opened.
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
