// Fuzz target: OpenIGTLink messages as the ingest receives them (imaging/igtl/image_message.h).
//
// The input is a byte stream of concatenated messages, read the way IngestClient reads a
// socket: 58 header bytes (ParseHeader), then for an IMAGE the 72-byte image header
// (ParseImageHeader, before anything is allocated), then the whole message (DecodeMessage);
// a bad_header or oversize body ends the stream, other rejections skip the message. The whole
// input is also decoded as one message with the CRC checked, as a client with default
// limits does. Each framed message also goes through the tracking decoders the EM stream
// client uses (imaging/igtl/tracking_messages.h: TRANSFORM, TDATA, POINT, STATUS and the
// version-2 metadata), whatever its type says. Only MessageError may escape the codec.
#include <cstddef>
#include <cstdint>
#include <span>

#include "imaging/igtl/image_message.h"
#include "imaging/igtl/tracking_messages.h"

namespace igtl = echoservo::imaging::openigtlink;

namespace {

void CheckVolume(const igtl::DecodedMessage& m) {
  if (!m.volume) return;
  const auto& v = *m.volume;
  // The decoded volume must be self-consistent; touching every voxel lets ASan check the
  // allocation matches the geometry.
  const auto& d = v.dims();
  const std::size_t n = static_cast<std::size_t>(d.x()) * d.y() * d.z();
  if (v.voxels().size() != n) __builtin_trap();
  volatile unsigned sum = 0;
  for (std::uint8_t x : v.voxels()) sum = sum + x;
  (void)v.Sample(v.IndexToPhysical((d.cast<double>() - Eigen::Vector3d::Ones()) / 2));
}

// The tracking decoders on one framed body; decoded values must be what they promise.
void DecodeTracking(const igtl::MessageHeader& header, std::span<const std::uint8_t> body) {
  auto check_rigid = [](const Eigen::Isometry3d& t) {
    const Eigen::Matrix3d r = t.linear();
    if (!t.matrix().allFinite()) __builtin_trap();
    if ((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-5)
      __builtin_trap();
  };
  auto as = [&](const char* type) {
    igtl::MessageHeader h = header;
    h.type = type;  // also decode bodies as the other types: more paths per input
    return h;
  };
  try {
    check_rigid(igtl::DecodeTransform(as("TRANSFORM"), body).transform);
  } catch (const igtl::MessageError&) {
  }
  try {
    for (const auto& e : igtl::DecodeTrackingData(as("TDATA"), body)) check_rigid(e.transform);
  } catch (const igtl::MessageError&) {
  }
  try {
    for (const auto& p : igtl::DecodePoints(as("POINT"), body))
      if (!p.position_mm.allFinite() || !(p.radius_mm >= 0)) __builtin_trap();
  } catch (const igtl::MessageError&) {
  }
  try {
    if (igtl::DecodeStatus(as("STATUS"), body).code > 19) __builtin_trap();
  } catch (const igtl::MessageError&) {
  }
  try {
    (void)igtl::DecodeMetadata(header, body);
  } catch (const igtl::MessageError&) {
  }
}

void ReadStream(std::span<const std::uint8_t> bytes, const igtl::DecodeLimits& limits) {
  while (bytes.size() >= igtl::kHeaderBytes) {
    igtl::MessageHeader header;
    try {
      header = igtl::ParseHeader(bytes.first(igtl::kHeaderBytes), limits);
    } catch (const igtl::MessageError&) {
      return;  // garbage framing: the ingest drops the connection
    }
    const std::size_t available = bytes.size() - igtl::kHeaderBytes;
    if (header.body_size > available) {
      // truncated_message: what the ingest sees when a connection closes mid-message.
      return;
    }
    const auto message = bytes.first(igtl::kHeaderBytes + header.body_size);
    DecodeTracking(header, message.subspan(igtl::kHeaderBytes));
    try {
      if (header.type == "IMAGE" && header.body_size >= igtl::kImageHeaderBytes) {
        const auto image = igtl::ParseImageHeader(
            header, message.subspan(igtl::kHeaderBytes, igtl::kImageHeaderBytes), limits);
        (void)image;
      }
      CheckVolume(igtl::DecodeMessage(message, limits));
    } catch (const igtl::MessageError&) {
    }
    bytes = bytes.subspan(message.size());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  igtl::DecodeLimits limits;
  limits.max_voxels = 1 << 20;  // keep executions fast; the checks are the same
  limits.max_body_bytes = (1u << 20) + 4096;
  try {
    CheckVolume(igtl::DecodeMessage(bytes, limits));
  } catch (const igtl::MessageError&) {
  }
  // Without the CRC the fuzzer reaches the image header and geometry checks.
  limits.verify_crc = false;
  ReadStream(bytes, limits);
  return 0;
}
