// Validating decoders of TRANSFORM, TDATA, POINT and STATUS bodies (tracking_messages.h).
// Every field is checked before it is used; nothing is allocated from a size that has not
// been checked against the body and the limits.
#include <Eigen/SVD>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "imaging/igtl/crc64.h"
#include "imaging/igtl/tracking_messages.h"

namespace echoservo::imaging::openigtlink {
namespace {

constexpr std::size_t kTdExtendedHeaderMinBytes = 12;
constexpr std::size_t kTdNameBytes = 20;
constexpr std::size_t kTdPointNameBytes = 64;
constexpr std::size_t kTdPointGroupBytes = 32;
constexpr std::uint16_t kTdMaxStatusCode = 19;
// Float32 round-off of a unit rotation: below this the rotation is taken as it is.
constexpr double kTdCleanRotationError = 1e-6;

std::uint16_t TdBe16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>((p[0] << 8) | p[1]);
}
std::uint32_t TdBe32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         std::uint32_t{p[3]};
}
std::uint64_t TdBe64(const std::uint8_t* p) {
  return (std::uint64_t{TdBe32(p)} << 32) | TdBe32(p + 4);
}
double TdBeFloat(const std::uint8_t* p) {
  const std::uint32_t bits = TdBe32(p);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return static_cast<double>(f);
}

std::string TdWhere(const MessageHeader& header) {
  return header.type + " '" + header.device_name + "'";
}

// Printable ASCII followed only by NULs (an empty name when allow_empty).
bool TdReadName(const std::uint8_t* field, std::size_t size, bool allow_empty, std::string& out) {
  std::size_t n = 0;
  while (n < size && field[n] != 0) {
    if (field[n] < 0x20 || field[n] > 0x7E) return false;
    ++n;
  }
  for (std::size_t i = n; i < size; ++i) {
    if (field[i] != 0) return false;
  }
  if (n == 0 && !allow_empty) return false;
  out.assign(reinterpret_cast<const char*>(field), n);
  return true;
}

void TdCheckType(const MessageHeader& header, const char* type) {
  if (header.type != type) {
    throw MessageError("wrong_type", "a " + header.type + " message given to the " +
                                         std::string(type) + " decoder");
  }
}

// The sizes of a version-2 body: extended header, content, metadata header, metadata.
struct TdV2Layout {
  std::size_t content_begin = 0, content_size = 0;
  std::size_t metadata_header_begin = 0, metadata_header_size = 0;
  std::size_t metadata_begin = 0, metadata_size = 0;
};

TdV2Layout TdReadV2Layout(const MessageHeader& header, std::span<const std::uint8_t> body) {
  if (body.size() < kTdExtendedHeaderMinBytes) {
    throw MessageError("bad_extended_header",
                       TdWhere(header) + ": version-2 body of " + std::to_string(body.size()) +
                           " bytes has no room for the 12-byte extended header");
  }
  TdV2Layout l;
  const std::size_t ext = TdBe16(body.data());
  l.metadata_header_size = TdBe16(body.data() + 2);
  l.metadata_size = TdBe32(body.data() + 4);
  if (ext < kTdExtendedHeaderMinBytes || ext > body.size() ||
      l.metadata_header_size + l.metadata_size > body.size() - ext) {
    throw MessageError("bad_extended_header",
                       TdWhere(header) + ": extended header " + std::to_string(ext) +
                           " + metadata header " + std::to_string(l.metadata_header_size) +
                           " + metadata " + std::to_string(l.metadata_size) +
                           " bytes do not fit the " + std::to_string(body.size()) + "-byte body");
  }
  l.content_begin = ext;
  l.content_size = body.size() - ext - l.metadata_header_size - l.metadata_size;
  l.metadata_header_begin = ext + l.content_size;
  l.metadata_begin = l.metadata_header_begin + l.metadata_header_size;
  return l;
}

// The content of a body: the whole body for version 1, without the extended header and
// metadata for version 2. Checks the span holds header.body_size bytes.
std::span<const std::uint8_t> TdContent(const MessageHeader& header,
                                        std::span<const std::uint8_t> body) {
  if (body.size() != header.body_size) {
    throw MessageError("bad_body_size", TdWhere(header) + ": " + std::to_string(body.size()) +
                                            " body bytes given, the header says " +
                                            std::to_string(header.body_size));
  }
  if (header.version < 2) return body;
  const TdV2Layout l = TdReadV2Layout(header, body);
  return body.subspan(l.content_begin, l.content_size);
}

// 12 big-endian floats: the rotation's columns, then the translation.
Eigen::Isometry3d TdReadRigid(const std::uint8_t* p, const TrackingDecodeLimits& limits,
                              const std::string& where, bool check_rotation,
                              bool& orthonormalized) {
  double v[12];
  for (int i = 0; i < 12; ++i) {
    v[i] = TdBeFloat(p + 4 * i);
    if (!std::isfinite(v[i])) {
      throw MessageError("non_finite", where + ": matrix element " + std::to_string(i) + " is " +
                                           std::to_string(v[i]));
    }
  }
  const Eigen::Vector3d t(v[9], v[10], v[11]);
  if (!(t.cwiseAbs().maxCoeff() <= limits.max_abs_position_mm)) {
    char buf[160];
    std::snprintf(buf, sizeof buf, ": translation (%g, %g, %g) mm beyond ±%g mm", t.x(), t.y(),
                  t.z(), limits.max_abs_position_mm);
    throw MessageError("out_of_range", where + buf);
  }
  Eigen::Matrix3d r;
  for (int c = 0; c < 3; ++c) r.col(c) = Eigen::Vector3d(v[3 * c], v[3 * c + 1], v[3 * c + 2]);
  orthonormalized = false;
  if (!check_rotation) {
    r.setIdentity();
  } else {
    const double err = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (!(err <= limits.orthonormal_tolerance)) {
      throw MessageError(
          "non_orthonormal",
          where + ": rotation columns not orthonormal (|RᵀR − I| = " + std::to_string(err) + " > " +
              std::to_string(limits.orthonormal_tolerance) + ")");
    }
    if (!(r.determinant() > 0)) {
      throw MessageError("non_orthonormal", where + ": the rotation is a reflection (det " +
                                                std::to_string(r.determinant()) + ")");
    }
    if (err > kTdCleanRotationError) {
      Eigen::JacobiSVD<Eigen::Matrix3d> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
      r = svd.matrixU() * svd.matrixV().transpose();
      orthonormalized = true;
    }
  }
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = r;
  out.translation() = t;
  return out;
}

// A whole number (≥ 1, ≤ limit) of fixed-size elements.
std::size_t TdElementCount(const MessageHeader& header, std::size_t content_size,
                           std::size_t element_bytes, const TrackingDecodeLimits& limits) {
  if (content_size == 0 || content_size % element_bytes != 0) {
    throw MessageError("bad_body_size", TdWhere(header) + ": " + std::to_string(content_size) +
                                            " content bytes are not a whole, non-zero number "
                                            "of " +
                                            std::to_string(element_bytes) + "-byte elements");
  }
  const std::size_t n = content_size / element_bytes;
  if (n > limits.max_elements) {
    throw MessageError("bad_body_size", TdWhere(header) + ": " + std::to_string(n) +
                                            " elements > limit " +
                                            std::to_string(limits.max_elements));
  }
  return n;
}

}  // namespace

void CheckBodyCrc(const MessageHeader& header, std::span<const std::uint8_t> body) {
  const std::uint64_t crc = Crc64Ecma182(body);
  if (crc != header.crc) {
    char buf[96];
    std::snprintf(buf, sizeof buf, ": body CRC-64 %016llx, header says %016llx",
                  static_cast<unsigned long long>(crc),
                  static_cast<unsigned long long>(header.crc));
    throw MessageError("bad_crc", TdWhere(header) + buf);
  }
}

TrackedTransform DecodeTransform(const MessageHeader& header, std::span<const std::uint8_t> body,
                                 const TrackingDecodeLimits& limits) {
  TdCheckType(header, "TRANSFORM");
  const auto content = TdContent(header, body);
  if (content.size() != kTransformBodyBytes) {
    throw MessageError("bad_body_size", TdWhere(header) + ": " + std::to_string(content.size()) +
                                            " content bytes, a TRANSFORM has 48");
  }
  TrackedTransform out;
  out.name = header.device_name;
  out.transform = TdReadRigid(content.data(), limits, TdWhere(header), true, out.orthonormalized);
  return out;
}

std::vector<TrackedTransform> DecodeTrackingData(const MessageHeader& header,
                                                 std::span<const std::uint8_t> body,
                                                 const TrackingDecodeLimits& limits) {
  TdCheckType(header, "TDATA");
  const auto content = TdContent(header, body);
  const std::size_t n = TdElementCount(header, content.size(), kTdataElementBytes, limits);
  std::vector<TrackedTransform> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* e = content.data() + i * kTdataElementBytes;
    const std::string where = TdWhere(header) + " element " + std::to_string(i);
    TrackedTransform& t = out[i];
    if (!TdReadName(e, kTdNameBytes, false, t.name)) {
      throw MessageError("bad_name", where + ": name is empty or not NUL-padded printable ASCII");
    }
    t.tdata_type = e[kTdNameBytes];
    // Type 3 (3D) carries a position only: its rotation is not defined.
    t.transform = TdReadRigid(e + kTdNameBytes + 2, limits, where + " '" + t.name + "'",
                              t.tdata_type != 3, t.orthonormalized);
  }
  return out;
}

std::vector<IgtlPoint> DecodePoints(const MessageHeader& header, std::span<const std::uint8_t> body,
                                    const TrackingDecodeLimits& limits) {
  TdCheckType(header, "POINT");
  const auto content = TdContent(header, body);
  const std::size_t n = TdElementCount(header, content.size(), kPointElementBytes, limits);
  std::vector<IgtlPoint> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* e = content.data() + i * kPointElementBytes;
    const std::string where = TdWhere(header) + " point " + std::to_string(i);
    IgtlPoint& p = out[i];
    if (!TdReadName(e, kTdPointNameBytes, true, p.name) ||
        !TdReadName(e + kTdPointNameBytes, kTdPointGroupBytes, true, p.group) ||
        !TdReadName(e + kTdPointNameBytes + kTdPointGroupBytes + 20, kTdNameBytes, true, p.owner)) {
      throw MessageError("bad_name",
                         where + ": name, group or owner is not NUL-padded printable ASCII");
    }
    const std::uint8_t* v = e + kTdPointNameBytes + kTdPointGroupBytes;
    std::copy(v, v + 4, p.rgba.begin());
    for (int k = 0; k < 3; ++k) p.position_mm[k] = TdBeFloat(v + 4 + 4 * k);
    p.radius_mm = TdBeFloat(v + 16);
    if (!p.position_mm.allFinite() || !std::isfinite(p.radius_mm)) {
      throw MessageError("non_finite", where + " '" + p.name +
                                           "': a NaN or infinite position "
                                           "or radius");
    }
    if (!(p.position_mm.cwiseAbs().maxCoeff() <= limits.max_abs_position_mm) ||
        !(p.radius_mm >= 0.0 && p.radius_mm <= limits.max_abs_position_mm)) {
      throw MessageError("out_of_range", where + " '" + p.name + "': position beyond ±" +
                                             std::to_string(limits.max_abs_position_mm) +
                                             " mm or a negative radius");
    }
  }
  return out;
}

IgtlStatus DecodeStatus(const MessageHeader& header, std::span<const std::uint8_t> body) {
  TdCheckType(header, "STATUS");
  const auto content = TdContent(header, body);
  if (content.size() < kStatusFixedBytes) {
    throw MessageError("bad_body_size", TdWhere(header) + ": " + std::to_string(content.size()) +
                                            " content bytes, a STATUS has at least 30");
  }
  IgtlStatus out;
  out.code = TdBe16(content.data());
  out.subcode = static_cast<std::int64_t>(TdBe64(content.data() + 2));
  if (out.code > kTdMaxStatusCode) {
    throw MessageError("bad_status",
                       TdWhere(header) + ": status code " + std::to_string(out.code) + " > 19");
  }
  if (!TdReadName(content.data() + 10, kTdNameBytes, true, out.error_name)) {
    throw MessageError("bad_name",
                       TdWhere(header) + ": error name is not NUL-padded printable ASCII");
  }
  const auto text = content.subspan(kStatusFixedBytes);
  if (!text.empty()) {
    if (text.back() != 0) {
      throw MessageError("bad_status", TdWhere(header) + ": the " + std::to_string(text.size()) +
                                           "-byte message does not end with a NUL");
    }
    const auto* chars = reinterpret_cast<const char*>(text.data());
    out.message.assign(chars, strnlen(chars, text.size()));
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> DecodeMetadata(
    const MessageHeader& header, std::span<const std::uint8_t> body) {
  std::vector<std::pair<std::string, std::string>> out;
  if (header.version < 2) return out;
  if (body.size() != header.body_size) {
    throw MessageError("bad_body_size", TdWhere(header) + ": " + std::to_string(body.size()) +
                                            " body bytes given, the header says " +
                                            std::to_string(header.body_size));
  }
  const TdV2Layout l = TdReadV2Layout(header, body);
  if (l.metadata_header_size == 0 && l.metadata_size == 0) return out;
  auto bad = [&](const std::string& why) {
    return MessageError("bad_extended_header", TdWhere(header) + ": metadata " + why);
  };
  if (l.metadata_header_size < 2) throw bad("header shorter than its 2-byte count");
  const std::uint8_t* mh = body.data() + l.metadata_header_begin;
  const std::size_t count = TdBe16(mh);
  if (l.metadata_header_size != 2 + 8 * count) {
    throw bad("header of " + std::to_string(l.metadata_header_size) + " bytes for " +
              std::to_string(count) + " entries (expected " + std::to_string(2 + 8 * count) + ")");
  }
  std::size_t at = l.metadata_begin;
  const std::size_t end = l.metadata_begin + l.metadata_size;
  out.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint8_t* entry = mh + 2 + 8 * i;
    const std::size_t key_size = TdBe16(entry);
    const std::size_t value_size = TdBe32(entry + 4);
    if (key_size > end - at || value_size > end - at - key_size) {
      throw bad("entry " + std::to_string(i) + " runs past the metadata's end");
    }
    std::string key(reinterpret_cast<const char*>(body.data() + at), key_size);
    at += key_size;
    std::string value(reinterpret_cast<const char*>(body.data() + at), value_size);
    at += value_size;
    out.emplace_back(std::move(key), std::move(value));
  }
  if (at != end)
    throw bad("entries do not add up to its " + std::to_string(l.metadata_size) + " bytes");
  return out;
}

}  // namespace echoservo::imaging::openigtlink
