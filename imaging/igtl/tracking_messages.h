// OpenIGTLink TRANSFORM, TDATA, POINT and STATUS messages: what echoservo sends a viewer (3D
// Slicer's OpenIGTLinkIF) about each processed volume, and what it accepts from a tracker
// server (PLUS) — encoders and validating decoders, beside the IMAGE codec (image_message.h).
//
// Wire: OpenIGTLink 1.11 (header version 1), 58-byte big-endian header with CRC-64, bodies
// as in the protocol's v2 message set: TRANSFORM 48 bytes (the upper 3×4 of the homogeneous
// matrix, column by column: x axis, y axis, z axis, translation; float32); TDATA 70 bytes an
// element (name[20], type, reserved, the same 12 floats); POINT 136 bytes an element
// (name[64], group[32], RGBA, position[3], radius, owner[20]); STATUS 30 bytes + a
// NUL-terminated message (code uint16, subcode int64, error name[20]).
// Units and frames: translations and positions in mm; a transform `AToB` maps A's coordinates
// into B's. The frame is whatever the caller says it is; encoders never flip axes (the caller
// converts LPS to RAS when it sends to a RAS viewer, image_message.h's FrameFlip convention).
// Time: 32.32 fixed-point s (MessageHeader::timestamp_s), s since the Unix epoch on a live link.
// Errors: decoders throw MessageError with a stable reason() (listed below, in addition to
// image_message.h's), the key of the receivers' rejection counters; encoders throw
// std::invalid_argument for a name too long, a non-finite value or a non-rigid rotation.
// Details: docs/openigtlink.md#tracking-messages
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "imaging/igtl/image_message.h"

namespace echoservo::imaging::openigtlink {

inline constexpr std::size_t kTransformBodyBytes = 48;
inline constexpr std::size_t kTdataElementBytes = 70;
inline constexpr std::size_t kPointElementBytes = 136;
inline constexpr std::size_t kStatusFixedBytes = 30;

// Decoder rejection reasons (MessageError::reason()), in addition to bad_header, bad_crc,
// truncated_message, body_too_large of ParseHeader/DecodeMessage:
//   wrong_type             the header's type is not the one the decoder reads
//   bad_body_size          TRANSFORM ≠ 48 bytes; TDATA, POINT not a whole number of elements
//                          (or none); STATUS < 30 bytes
//   non_finite             a NaN or infinite value in a matrix or position
//   non_orthonormal        rotation columns not orthonormal within
//                          TrackingDecodeLimits::orthonormal_tolerance, or a reflection
//   out_of_range           a translation or position beyond max_abs_position_mm
//   bad_name               an element name, group or owner with bytes that are not printable
//                          ASCII followed by NULs
//   bad_status             STATUS code beyond 19 or a message without its terminating NUL
//   bad_extended_header    header version 2: an extended header < 12 bytes, sizes that do not
//                          add up to the body, or metadata that is not as its header says
struct TrackingDecodeLimits {
  // |RᵀR − I| (max element) above this is rejected; float32 round-off is ~1e-7. Up to it the
  // rotation is re-orthonormalised (polar decomposition) and the result says so.
  double orthonormal_tolerance = 1e-3;
  double max_abs_position_mm = 1e5;  // 100 m: anything beyond is a unit or framing error
  std::size_t max_elements = 256;    // TDATA and POINT elements a message
};

// One rigid transform (TRANSFORM, or one TDATA element).
struct TrackedTransform {
  std::string name;  // TRANSFORM: the header's device name; TDATA: the element's name
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();  // mm
  std::uint8_t tdata_type = 0;   // TDATA: 1 tracker, 2 6D, 3 3D, 4 5D; 0 for TRANSFORM
  bool orthonormalized = false;  // the rotation was re-orthonormalised on decoding
};

// One POINT element.
struct IgtlPoint {
  std::string name;   // ≤ 63 bytes
  std::string group;  // ≤ 31 bytes
  std::array<std::uint8_t, 4> rgba{255, 255, 255, 255};
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  double radius_mm = 0.0;
  std::string owner;  // ≤ 19 bytes: the device name of an IMAGE it belongs to, or empty
};

// STATUS codes of the protocol (subset used here; 0..19 are valid on the wire).
enum class StatusCode : std::uint16_t {
  kInvalid = 0,
  kOk = 1,
  kUnknownError = 2,
  kNotFound = 4,
  kTimeOut = 7,
  kNotReady = 13,
  kDisabled = 15,
};

struct IgtlStatus {
  std::uint16_t code = static_cast<std::uint16_t>(StatusCode::kOk);
  std::int64_t subcode = 0;
  std::string error_name;  // ≤ 19 bytes
  std::string message;
};

// Encoders: one complete message (header + body) into `out` (resized; reuse it). The
// timestamp goes through SecondsToIgtlTimestamp (throws outside [0, 2³²) s); device names
// are at most 20 bytes of printable ASCII.
void EncodeTransform(const std::string& device_name, double timestamp_s,
                     const Eigen::Isometry3d& transform, std::vector<std::uint8_t>& out);
void EncodeTrackingData(const std::string& device_name, double timestamp_s,
                        const std::vector<TrackedTransform>& elements,
                        std::vector<std::uint8_t>& out);
void EncodePoints(const std::string& device_name, double timestamp_s,
                  const std::vector<IgtlPoint>& points, std::vector<std::uint8_t>& out);
void EncodeStatus(const std::string& device_name, double timestamp_s, const IgtlStatus& status,
                  std::vector<std::uint8_t>& out);

// Decoders: `header` from ParseHeader, `body` its body_size bytes, CRC already checked
// (DecodeMessage does, or CheckBodyCrc). Throw MessageError (reasons above).
TrackedTransform DecodeTransform(const MessageHeader& header, std::span<const std::uint8_t> body,
                                 const TrackingDecodeLimits& limits = {});
std::vector<TrackedTransform> DecodeTrackingData(const MessageHeader& header,
                                                 std::span<const std::uint8_t> body,
                                                 const TrackingDecodeLimits& limits = {});
std::vector<IgtlPoint> DecodePoints(const MessageHeader& header, std::span<const std::uint8_t> body,
                                    const TrackingDecodeLimits& limits = {});
IgtlStatus DecodeStatus(const MessageHeader& header, std::span<const std::uint8_t> body);

// Header version 2 (OpenIGTLink 3): the body is an extended header, the content, then
// metadata (key/value pairs); the decoders above read the content of either version. This
// returns the metadata (empty for version 1). PLUS states a tool's status there
// ("TransformStatus"; TDATA: "<element name>Status"; values "OK", "MISSING", "INVALID", …).
// Throws MessageError("bad_extended_header").
std::vector<std::pair<std::string, std::string>> DecodeMetadata(const MessageHeader& header,
                                                                std::span<const std::uint8_t> body);

// Throws MessageError("bad_crc") when the body's CRC-64 differs from the header's.
void CheckBodyCrc(const MessageHeader& header, std::span<const std::uint8_t> body);

// A catheter frame from a detection: origin at the tip, z along the axis (unit, towards the
// tip), x and y completing a right-handed frame (x chosen stably: the image axis least
// aligned with z, made orthogonal). Throws std::invalid_argument for a zero or non-finite axis.
Eigen::Isometry3d CatheterFrame(const Eigen::Vector3d& tip_mm, const Eigen::Vector3d& axis);

}  // namespace echoservo::imaging::openigtlink
