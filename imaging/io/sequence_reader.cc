#include "imaging/io/sequence_reader.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "imaging/io/plus_sequence_internal.h"

namespace echoservo::imaging {
namespace ii = io_internal;

namespace {

// Streamed sequences: any total the file holds (the layout check still requires every
// declared byte to be present), each frame within the whole-file readers' cap.
constexpr std::uint64_t kMaxStreamedBytes = std::numeric_limits<std::int64_t>::max();

}  // namespace

SequenceReader::SequenceReader(const std::filesystem::path& path) : path_(path) {
  ii::SequenceHeader h = ii::ReadSequenceHeader(path, kMaxStreamedBytes);
  sequence_ = std::move(h.sequence);
  const std::string where = h.text.Where();
  if (sequence_.FrameBytes() > ii::kMaxPixelBytes) {
    throw std::invalid_argument(where + "one frame is " + std::to_string(sequence_.FrameBytes()) +
                                " bytes, more than the " + ii::ByteCapText(ii::kMaxPixelBytes) +
                                " cap");
  }
  if (h.layout.pixel_bytes == 0) return;  // tracker-only: fields, no pixels
  if (h.layout.compressed) {
    if (h.layout.pixel_bytes > ii::kMaxPixelBytes) {
      throw std::invalid_argument(
          where + "compressed pixel data of " + std::to_string(h.layout.pixel_bytes) +
          " bytes exceeds the " + ii::ByteCapText(ii::kMaxPixelBytes) +
          " cap (a compressed stream is read whole; write long recordings uncompressed)");
    }
    sequence_.pixels = ii::ReadPixels(h.text, h.layout);
    return;
  }
  data_path_ = h.text.data_path;
  data_offset_ = h.text.data_offset;
  fd_ = ::open(data_path_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) {
    throw std::invalid_argument(data_path_.string() +
                                ": cannot open for reading: " + std::strerror(errno));
  }
}

SequenceReader::~SequenceReader() {
  if (fd_ >= 0) ::close(fd_);
}

Volume SequenceReader::ReadVolume(std::size_t frame) {
  if (!streamed() || frame >= size())
    return SequenceFrameToVolume(sequence_, frame);  // it checks the range
  const std::uint64_t n = sequence_.FrameBytes();
  buffer_.resize(static_cast<std::size_t>(n));
  std::uint64_t done = 0;
  const std::uint64_t offset = data_offset_ + frame * n;
  while (done < n) {
    const ssize_t r = ::pread(fd_, buffer_.data() + done, static_cast<std::size_t>(n - done),
                              static_cast<off_t>(offset + done));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) {
      throw std::invalid_argument(data_path_.string() + ": frame " + std::to_string(frame) + ": " +
                                  (r < 0
                                       ? std::string("read failed: ") + std::strerror(errno)
                                       : "the file ends at byte " + std::to_string(offset + done) +
                                             " (it has shrunk since it was opened)"));
    }
    done += static_cast<std::uint64_t>(r);
  }
  return SequenceFrameToVolume(sequence_, frame, buffer_);
}

}  // namespace echoservo::imaging
