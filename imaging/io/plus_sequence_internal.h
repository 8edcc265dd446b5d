// Internal to imaging/io: a PLUS sequence's header and frame fields without its pixels,
// shared by ReadPlusSequence (which then reads all pixels) and SequenceReader (which reads
// one frame's pixels at a time). Errors: std::invalid_argument naming the file.
#pragma once

#include <cstdint>
#include <filesystem>

#include "imaging/io/metaio_internal.h"
#include "imaging/io/plus_sequence.h"

namespace echoservo::imaging::io_internal {

// At most this many frames in a sequence: the frame fields are held in memory (about 50 bytes
// each before any field), and a header could otherwise declare billions of 1-byte frames.
// 2^20 frames: 11.6 h of volumes at 25 vol/s.
inline constexpr std::uint64_t kMaxSequenceFrames = 1ULL << 20;

struct SequenceHeader {
  PlusSequence sequence;  // everything but `pixels` (left empty)
  TextHeader text;        // where the pixel data is (data_path, data_offset)
  PixelLayout layout;     // its size and compression
};

// `max_pixel_bytes` caps the declared pixel data of all frames (CheckPixelLayout).
SequenceHeader ReadSequenceHeader(const std::filesystem::path& path, std::uint64_t max_pixel_bytes);

}  // namespace echoservo::imaging::io_internal
