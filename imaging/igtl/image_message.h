// OpenIGTLink IMAGE messages <-> imaging::Volume, and validation of untrusted bytes.
//
// Wire: OpenIGTLink 1.11 (header version 1, version-2 message set), 58-byte big-endian header,
// 72-byte image header, voxels i fastest. Frames: our image frame is LPS in mm; the 3×4 IMAGE
// matrix holds the axes × spacing and the volume's CENTRE (not voxel 0), in RAS (encoded by
// default) or LPS.
// Time: 32.32 fixed-point s = Volume::timestamp_s, no epoch shift. Only uint8, 1 component,
// full volumes are accepted.
// Errors: every rejection throws MessageError with a stable reason() (listed below), the key
// of the ingest's rejection counters; nothing is allocated from header fields before they
// pass DecodeLimits.
// Details: docs/openigtlink.md#the-image-codec-imagingigtlimage_messageh
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "imaging/volume.h"

namespace echoservo::imaging::openigtlink {

inline constexpr std::size_t kHeaderBytes = 58;
inline constexpr std::size_t kImageHeaderBytes = 72;

// Rejection reasons (MessageError::reason()):
//   bad_header            version not 1/2, or type/device name not printable NUL-padded ASCII
//                         (garbage: a stream reader cannot resynchronise after it)
//   body_too_large        header body_size > DecodeLimits::max_body_bytes
//   bad_crc               CRC-64 of the body ≠ header crc
//   truncated_message     fewer bytes than the header announces (a dropped connection)
//   unsupported_header_version  an IMAGE with header version 2 (extended header)
//   bad_image_header      IMAGE body < 72 bytes, image-header version ≠ 1, bad endian
//   unsupported_image     scalar type ≠ uint8, components ≠ 1, or a sub-volume
//   bad_coordinate_system coord not 1 (RAS) or 2 (LPS)
//   too_many_voxels       dims product > DecodeLimits::max_voxels (checked before allocating)
//   body_size_mismatch    body_size ≠ 72 + dims product × scalar size
//   bad_geometry          a zero dim, zero/non-finite spacing, non-orthonormal axes
class MessageError : public std::runtime_error {
 public:
  MessageError(std::string reason, const std::string& detail)
      : std::runtime_error(reason + ": " + detail), reason_(std::move(reason)) {}
  const std::string& reason() const { return reason_; }

 private:
  std::string reason_;
};

struct DecodeLimits {
  std::int64_t max_voxels = 64LL << 20;                 // dims product of an IMAGE (64 Mi voxels)
  std::uint64_t max_body_bytes = (64ULL << 20) + 4096;  // any message type
  bool verify_crc = true;
  // Axes whose float32 orthonormality error lies in (1e-6, this] are re-orthonormalised
  // (polar decomposition) instead of rejected.
  double orthonormalize_tolerance = 1e-3;
};

enum class CoordinateSystem : std::uint8_t { kRas = 1, kLps = 2 };

struct MessageHeader {
  std::uint16_t version = 1;
  std::string type;  // "IMAGE", "STATUS", ... (NUL padding removed)
  std::string device_name;
  std::uint64_t timestamp = 0;  // raw 32.32 fixed point
  std::uint64_t body_size = 0;
  std::uint64_t crc = 0;
  double timestamp_s() const;
};

// 32.32 fixed-point timestamp <-> seconds. Negative or non-finite seconds throw
// std::invalid_argument; values ≥ 2³² s as well.
std::uint64_t SecondsToIgtlTimestamp(double seconds);
double IgtlTimestampToSeconds(std::uint64_t timestamp);

// A validated IMAGE body header.
struct ImageHeader {
  CoordinateSystem coordinate_system = CoordinateSystem::kRas;
  std::array<float, 12> matrix{};  // as on the wire (host byte order)
  Eigen::Vector3d center_mm;       // matrix[9..11], in the message's coordinate system
  VolumeGeometry geometry;         // echoservo image frame (LPS), origin at voxel 0
  bool orthonormalized = false;    // axes were re-orthonormalised (see DecodeLimits)
  std::uint64_t voxel_bytes = 0;   // dims product × 1
};

// Parses and checks the 58 header bytes (`bytes` must hold at least 58). Throws
// MessageError: bad_header, body_too_large.
MessageHeader ParseHeader(std::span<const std::uint8_t> bytes, const DecodeLimits& limits);

// Parses and checks the first 72 body bytes of an IMAGE against `header` and the limits,
// without allocating anything. Throws MessageError (see the reasons above).
ImageHeader ParseImageHeader(const MessageHeader& header, std::span<const std::uint8_t> bytes,
                             const DecodeLimits& limits);

// A Volume with `image`'s geometry, timestamp from `header`, voxels uninitialised (zero).
Volume MakeVolume(const MessageHeader& header, const ImageHeader& image);

struct DecodedMessage {
  MessageHeader header;
  std::optional<ImageHeader> image;  // IMAGE only
  std::optional<Volume> volume;      // IMAGE only; nullopt: a valid non-IMAGE message, skipped
};

// Decodes one complete message (header + body; trailing bytes are an error). Checks the
// header, the CRC (every type), and for IMAGE the image header and sizes. Throws
// MessageError. Non-IMAGE types come back with volume == nullopt.
DecodedMessage DecodeMessage(std::span<const std::uint8_t> message, const DecodeLimits& limits);

struct EncodeOptions {
  std::string device_name = "echoservo";  // at most 20 bytes (longer throws)
  CoordinateSystem coordinate_system = CoordinateSystem::kRas;
  bool libigtl_crc = false;  // compute the CRC with libOpenIGTLink's crc64 (benchmarks)
};

// Size in bytes of the encoded message.
std::size_t EncodedImageSize(const Volume& volume);
// Encodes `volume` as an IMAGE message into `out` (resized; reuse it to avoid allocation).
// Throws std::invalid_argument if a dim exceeds 65535 or the device name is too long.
void EncodeImage(const Volume& volume, const EncodeOptions& options,
                 std::vector<std::uint8_t>& out);
std::vector<std::uint8_t> EncodeImage(const Volume& volume, const EncodeOptions& options = {});
// The same message built by libOpenIGTLink (igtl::ImageMessage::Pack): the reference for
// conformance tests and the benchmark.
std::vector<std::uint8_t> EncodeImageLibIgtl(const Volume& volume,
                                             const EncodeOptions& options = {});

// Writes the 58-byte header of a message of `type` (≤ 12 bytes) from `device_name` (≤ 20
// bytes of printable ASCII) at `timestamp_s` whose body is `body` (size and CRC-64 taken from
// it) into out[0, 58). Throws std::invalid_argument for a name too long or not printable, or a
// timestamp outside [0, 2³²) s. Shared by the tracking message encoders (tracking_messages.h).
void WriteMessageHeader(const std::string& type, const std::string& device_name, double timestamp_s,
                        std::span<const std::uint8_t> body, std::uint8_t* out);

// The volume's wire matrix (12 floats, see above) in `coordinate_system`.
std::array<float, 12> ImageMatrix(const VolumeGeometry& geometry,
                                  CoordinateSystem coordinate_system);

// Seconds since the Unix epoch on the system clock: the clock OpenIGTLink timestamps use.
double WallClockSeconds();

}  // namespace echoservo::imaging::openigtlink
