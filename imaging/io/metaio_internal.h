// Internal to imaging/io: the text headers of MetaImage (.mha/.mhd) and NRRD files, parsed
// without trusting them, plus zlib helpers. Used by volume_io.cc (to validate a file before
// VTK allocates anything, and to recover fields VTK drops) and plus_sequence.cc (which reads
// and writes the whole file itself). No VTK here.
//
// Errors: std::invalid_argument whose message starts with the file path and names the
// field or the problem.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace echoservo::imaging::io_internal {

// Cap on the pixel data any reader here will allocate for one file.
inline constexpr std::uint64_t kMaxPixelBytes = 4ULL << 30;  // 4 GiB
// zlib cannot expand data by more than ~1032:1; a header claiming more is a lie.
inline constexpr std::uint64_t kMaxDeflateRatio = 1032;
// Cap on a text header (a PLUS sequence with 100k frames is ~100 MB of header).
inline constexpr std::uint64_t kMaxHeaderBytes = 512ULL << 20;

enum class HeaderSyntax { kMetaImage, kNrrd };

// One parsed header, keys in file order. MetaImage `Key = Value`; NRRD `field: value` and
// `key:=value` (both stored as key/value; `nrrd_keyvalue` tells which).
struct TextHeader {
  struct Entry {
    std::string key;
    std::string value;  // surrounding whitespace trimmed
    bool nrrd_keyvalue = false;
  };
  HeaderSyntax syntax = HeaderSyntax::kMetaImage;
  std::vector<Entry> entries;
  std::filesystem::path path;        // the header file
  std::filesystem::path data_path;   // where the pixel data lies (== path when LOCAL)
  std::uint64_t data_offset = 0;     // byte offset of the pixel data in data_path
  std::uint64_t data_available = 0;  // bytes from data_offset to the end of data_path

  // The value of the last entry with this key (MetaImage keys are case-sensitive, NRRD
  // field names are compared case-insensitively), or nullopt.
  std::optional<std::string> Find(const std::string& key) const;
  // As Find, but throws naming the file and key when absent.
  std::string Require(const std::string& key) const;
  // "<path>: " for messages.
  std::string Where() const { return path.string() + ": "; }
};

// Reads the header of a MetaImage or NRRD file (chosen by the first bytes: "NRRD" or not).
// Checks the file exists, is a regular file, and that the header ends (ElementDataFile for
// MetaImage, a blank line for NRRD) within kMaxHeaderBytes.
TextHeader ReadTextHeader(const std::filesystem::path& path);

// Pixel layout a header declares, checked: dims (≥ 0 each), element type and size,
// compression, total bytes within `max_pixel_bytes` and consistent with the bytes available.
// Readers that allocate the whole pixel data keep the 4 GiB default; a reader that streams
// uncompressed frames from the file may allow more (the data must still be in the file).
struct PixelLayout {
  std::vector<std::int64_t> dims;     // DimSize / sizes, fastest first
  std::string element_type;           // MetaImage spelling, e.g. MET_UCHAR (NRRD types mapped)
  int element_size = 0;               // bytes; 0 for MET_OTHER (allowed only with no pixels)
  bool compressed = false;            // zlib (MetaImage) or gzip (NRRD "gz")
  std::uint64_t compressed_size = 0;  // bytes of compressed stream to read (when compressed)
  std::uint64_t pixel_bytes = 0;      // product(dims) · element_size
  // NRRD geometry (space directions / space origin), when given.
  std::vector<std::vector<double>> nrrd_space_directions;  // one per axis; empty = "none"
  std::vector<double> nrrd_space_origin;
};
PixelLayout CheckPixelLayout(const TextHeader& header,
                             std::uint64_t max_pixel_bytes = kMaxPixelBytes);
// "4 GiB" for messages about a cap in bytes.
std::string ByteCapText(std::uint64_t bytes);

// Reads and (if compressed) inflates the pixel data the layout describes. Throws naming the
// file on a truncated/corrupt stream or a size mismatch.
std::vector<std::uint8_t> ReadPixels(const TextHeader& header, const PixelLayout& layout);

// zlib/gzip inflate of exactly `expected` bytes (inflateInit2 with automatic header
// detection). Throws std::invalid_argument prefixed by `where` when the stream is corrupt,
// ends early, or holds more than expected.
std::vector<std::uint8_t> Inflate(std::span<const std::uint8_t> in, std::uint64_t expected,
                                  const std::string& where);
// zlib (gzip = false) or gzip (gzip = true) deflate.
std::vector<std::uint8_t> Deflate(std::span<const std::uint8_t> in, bool gzip);

// Whitespace-separated numbers; throws naming `where` on anything that is not a finite number.
std::vector<double> ParseNumbers(const std::string& text, const std::string& where);
std::int64_t ParseInteger(const std::string& text, const std::string& where);
std::string Trim(const std::string& s);
// "%.17g" — shortest text that reads back to the same double is not needed, exactness is.
std::string FormatNumber(double v);

// Bytes of one MetaImage element type (0 for MET_OTHER); nullopt for unknown names.
std::optional<int> MetaElementSize(const std::string& element_type);

}  // namespace echoservo::imaging::io_internal
