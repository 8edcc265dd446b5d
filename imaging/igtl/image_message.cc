#include "imaging/igtl/image_message.h"

#include <igtlImageMessage.h>
#include <igtl_header.h>
#include <igtl_image.h>

#include <Eigen/SVD>
#include <chrono>
#include <cmath>
#include <cstring>

#include "imaging/igtl/crc64.h"

namespace echoservo::imaging::openigtlink {
namespace {

static_assert(sizeof(igtl_header) == kHeaderBytes);
static_assert(sizeof(igtl_image_header) == kImageHeaderBytes);

// Printable ASCII followed only by NULs; `allow_empty` for device names.
bool ParseName(const char* field, std::size_t size, bool allow_empty, std::string& out) {
  std::size_t n = 0;
  while (n < size && field[n] != '\0') {
    const auto c = static_cast<unsigned char>(field[n]);
    if (c < 0x20 || c > 0x7E) return false;
    ++n;
  }
  for (std::size_t i = n; i < size; ++i) {
    if (field[i] != '\0') return false;
  }
  if (n == 0 && !allow_empty) return false;
  out.assign(field, n);
  return true;
}

Eigen::Matrix3d FrameFlip(CoordinateSystem cs) {
  // RAS <-> LPS: x and y change sign. LPS is echoservo's image frame.
  return cs == CoordinateSystem::kRas ? Eigen::Vector3d(-1, -1, 1).asDiagonal().toDenseMatrix()
                                      : Eigen::Matrix3d::Identity();
}

void CheckCrc(const MessageHeader& header, std::uint64_t crc) {
  if (crc != header.crc) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "body CRC-64 %016llx, header says %016llx",
                  static_cast<unsigned long long>(crc),
                  static_cast<unsigned long long>(header.crc));
    throw MessageError("bad_crc", buf);
  }
}

}  // namespace

double MessageHeader::timestamp_s() const { return IgtlTimestampToSeconds(timestamp); }

std::uint64_t SecondsToIgtlTimestamp(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0.0 || seconds >= 4294967296.0) {
    throw std::invalid_argument("OpenIGTLink timestamp: " + std::to_string(seconds) +
                                " s is outside [0, 2^32) s");
  }
  const double whole = std::floor(seconds);
  auto sec = static_cast<std::uint64_t>(whole);
  double frac = std::round((seconds - whole) * 4294967296.0);
  if (frac >= 4294967296.0) {  // rounding carried into the seconds
    frac = 0.0;
    ++sec;
  }
  return (sec << 32) | static_cast<std::uint64_t>(frac);
}

double IgtlTimestampToSeconds(std::uint64_t timestamp) {
  return static_cast<double>(timestamp >> 32) +
         static_cast<double>(timestamp & 0xFFFFFFFFULL) / 4294967296.0;
}

MessageHeader ParseHeader(std::span<const std::uint8_t> bytes, const DecodeLimits& limits) {
  if (bytes.size() < kHeaderBytes) {
    throw MessageError("truncated_message",
                       "header has " + std::to_string(bytes.size()) + " of 58 bytes");
  }
  igtl_header h;
  std::memcpy(&h, bytes.data(), kHeaderBytes);
  igtl_header_convert_byte_order(&h);
  MessageHeader out;
  out.version = h.version;
  if (h.version != 1 && h.version != 2) {
    throw MessageError("bad_header",
                       "header version " + std::to_string(h.version) + " (expected 1 or 2)");
  }
  if (!ParseName(h.name, IGTL_HEADER_TYPE_SIZE, false, out.type)) {
    throw MessageError("bad_header", "message type is not NUL-padded printable ASCII");
  }
  if (!ParseName(h.device_name, IGTL_HEADER_NAME_SIZE, true, out.device_name)) {
    throw MessageError("bad_header", "device name is not NUL-padded printable ASCII");
  }
  out.timestamp = h.timestamp;
  out.body_size = h.body_size;
  out.crc = h.crc;
  if (out.body_size > limits.max_body_bytes) {
    throw MessageError("body_too_large", out.type + " body of " + std::to_string(out.body_size) +
                                             " bytes > limit " +
                                             std::to_string(limits.max_body_bytes));
  }
  return out;
}

ImageHeader ParseImageHeader(const MessageHeader& header, std::span<const std::uint8_t> bytes,
                             const DecodeLimits& limits) {
  if (header.version != 1) {
    throw MessageError(
        "unsupported_header_version",
        "IMAGE with header version " + std::to_string(header.version) + " (only 1 is supported)");
  }
  if (header.body_size < kImageHeaderBytes || bytes.size() < kImageHeaderBytes) {
    throw MessageError("bad_image_header", "IMAGE body of " + std::to_string(header.body_size) +
                                               " bytes is shorter than its 72-byte image header");
  }
  igtl_image_header ih;
  std::memcpy(&ih, bytes.data(), kImageHeaderBytes);
  igtl_image_convert_byte_order(&ih);
  if (ih.version != IGTL_IMAGE_HEADER_VERSION) {
    throw MessageError("bad_image_header",
                       "image header version " + std::to_string(ih.version) + " (expected 1)");
  }
  if (ih.endian != IGTL_IMAGE_ENDIAN_BIG && ih.endian != IGTL_IMAGE_ENDIAN_LITTLE) {
    throw MessageError("bad_image_header", "endian field " + std::to_string(ih.endian));
  }
  if (ih.scalar_type != IGTL_IMAGE_STYPE_TYPE_UINT8) {
    throw MessageError("unsupported_image",
                       "scalar type " + std::to_string(ih.scalar_type) + " (only 3 = uint8)");
  }
  if (ih.num_components != 1) {
    throw MessageError("unsupported_image",
                       std::to_string(ih.num_components) + " components (only 1)");
  }
  if (ih.coord != IGTL_IMAGE_COORD_RAS && ih.coord != IGTL_IMAGE_COORD_LPS) {
    throw MessageError("bad_coordinate_system",
                       "coordinate system " + std::to_string(ih.coord) + " (1 = RAS, 2 = LPS)");
  }
  // Sizes: check the product against the limit before anything is allocated.
  const std::int64_t voxels = static_cast<std::int64_t>(ih.size[0]) * ih.size[1] * ih.size[2];
  if (voxels > limits.max_voxels) {
    throw MessageError("too_many_voxels",
                       std::to_string(ih.size[0]) + "x" + std::to_string(ih.size[1]) + "x" +
                           std::to_string(ih.size[2]) + " = " + std::to_string(voxels) +
                           " voxels > limit " + std::to_string(limits.max_voxels));
  }
  const std::uint64_t expected = kImageHeaderBytes + static_cast<std::uint64_t>(voxels);
  if (header.body_size != expected) {
    throw MessageError("body_size_mismatch", "body_size " + std::to_string(header.body_size) +
                                                 " != 72 + " + std::to_string(voxels) +
                                                 " voxels x 1 byte");
  }
  for (int a = 0; a < 3; ++a) {
    if (ih.subvol_offset[a] != 0 || ih.subvol_size[a] != ih.size[a]) {
      throw MessageError("unsupported_image", "sub-volume messages are not supported");
    }
  }
  if (voxels == 0) throw MessageError("bad_geometry", "a dimension is 0");

  ImageHeader out;
  out.coordinate_system = static_cast<CoordinateSystem>(ih.coord);
  std::copy(std::begin(ih.matrix), std::end(ih.matrix), out.matrix.begin());
  const Eigen::Matrix3d flip = FrameFlip(out.coordinate_system);
  Eigen::Matrix3d scaled;  // columns: direction · spacing, in LPS
  for (int c = 0; c < 3; ++c) {
    scaled.col(c) =
        flip * Eigen::Vector3d(ih.matrix[3 * c], ih.matrix[3 * c + 1], ih.matrix[3 * c + 2]);
  }
  out.center_mm = Eigen::Vector3d(ih.matrix[9], ih.matrix[10], ih.matrix[11]);
  VolumeGeometry& g = out.geometry;
  g.dims = Eigen::Vector3i(ih.size[0], ih.size[1], ih.size[2]);
  for (int c = 0; c < 3; ++c) {
    const double s = scaled.col(c).norm();
    if (!std::isfinite(s) || s <= 0.0) {
      throw MessageError("bad_geometry",
                         "axis " + std::to_string(c) + " has zero or non-finite spacing");
    }
    g.spacing_mm[c] = s;
    g.direction.col(c) = scaled.col(c) / s;
  }
  const double err =
      (g.direction.transpose() * g.direction - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(err <= VolumeGeometry::kOrthonormalTolerance)) {
    if (!(err <= limits.orthonormalize_tolerance)) {
      throw MessageError("bad_geometry",
                         "axes are not orthonormal (error " + std::to_string(err) + ")");
    }
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(g.direction, Eigen::ComputeFullU | Eigen::ComputeFullV);
    g.direction = svd.matrixU() * svd.matrixV().transpose();
    out.orthonormalized = true;
  }
  const Eigen::Vector3d half = (g.dims.cast<double>() - Eigen::Vector3d::Ones()) / 2.0;
  g.origin_mm = flip * out.center_mm - g.direction * half.cwiseProduct(g.spacing_mm);
  try {
    g.Validate("OpenIGTLink IMAGE");
  } catch (const std::invalid_argument& e) {
    throw MessageError("bad_geometry", e.what());
  }
  out.voxel_bytes = static_cast<std::uint64_t>(voxels);
  return out;
}

Volume MakeVolume(const MessageHeader& header, const ImageHeader& image) {
  Volume v = Volume::Create(image.geometry);
  v.set_timestamp_s(header.timestamp_s());
  return v;
}

DecodedMessage DecodeMessage(std::span<const std::uint8_t> message, const DecodeLimits& limits) {
  DecodedMessage out;
  out.header = ParseHeader(message, limits);
  const std::uint64_t have = message.size() - kHeaderBytes;
  if (have < out.header.body_size) {
    throw MessageError("truncated_message", "body has " + std::to_string(have) + " of " +
                                                std::to_string(out.header.body_size) + " bytes");
  }
  if (have > out.header.body_size) {
    throw MessageError("body_size_mismatch", std::to_string(have - out.header.body_size) +
                                                 " bytes after the announced body");
  }
  const auto body = message.subspan(kHeaderBytes);
  if (out.header.type != "IMAGE") {
    if (limits.verify_crc) CheckCrc(out.header, Crc64Ecma182(body));
    return out;
  }
  out.image = ParseImageHeader(out.header, body, limits);
  if (limits.verify_crc) CheckCrc(out.header, Crc64Ecma182(body));
  out.volume = MakeVolume(out.header, *out.image);
  std::memcpy(out.volume->voxels().data(), body.data() + kImageHeaderBytes, out.image->voxel_bytes);
  return out;
}

std::array<float, 12> ImageMatrix(const VolumeGeometry& g, CoordinateSystem cs) {
  const Eigen::Matrix3d flip = FrameFlip(cs);
  std::array<float, 12> m{};
  for (int c = 0; c < 3; ++c) {
    const Eigen::Vector3d col = flip * g.direction.col(c) * g.spacing_mm[c];
    for (int r = 0; r < 3; ++r) m[3 * c + r] = static_cast<float>(col[r]);
  }
  const Eigen::Vector3d half = (g.dims.cast<double>() - Eigen::Vector3d::Ones()) / 2.0;
  const Eigen::Vector3d center =
      flip * (g.origin_mm + g.direction * half.cwiseProduct(g.spacing_mm));
  for (int r = 0; r < 3; ++r) m[9 + r] = static_cast<float>(center[r]);
  return m;
}

std::size_t EncodedImageSize(const Volume& volume) {
  return kHeaderBytes + kImageHeaderBytes + volume.voxel_count();
}

namespace {

void CheckEncodable(const Volume& volume, const EncodeOptions& options) {
  if (options.device_name.size() > IGTL_HEADER_NAME_SIZE) {
    throw std::invalid_argument("OpenIGTLink device name '" + options.device_name +
                                "' is longer than 20 bytes");
  }
  for (int a = 0; a < 3; ++a) {
    if (volume.dims()[a] > 65535) {
      throw std::invalid_argument("OpenIGTLink IMAGE: dimension " +
                                  std::to_string(volume.dims()[a]) + " exceeds 65535");
    }
  }
}

}  // namespace

void EncodeImage(const Volume& volume, const EncodeOptions& options,
                 std::vector<std::uint8_t>& out) {
  CheckEncodable(volume, options);
  out.resize(EncodedImageSize(volume));
  std::uint8_t* body = out.data() + kHeaderBytes;

  igtl_image_header ih{};
  ih.version = IGTL_IMAGE_HEADER_VERSION;
  ih.num_components = 1;
  ih.scalar_type = IGTL_IMAGE_STYPE_TYPE_UINT8;
  ih.endian = IGTL_IMAGE_ENDIAN_LITTLE;
  ih.coord = static_cast<igtl_uint8>(options.coordinate_system);
  const auto m = ImageMatrix(volume.geometry(), options.coordinate_system);
  for (int a = 0; a < 3; ++a) {
    ih.size[a] = static_cast<igtl_uint16>(volume.dims()[a]);
    ih.subvol_offset[a] = 0;
    ih.subvol_size[a] = ih.size[a];
  }
  std::copy(m.begin(), m.end(), ih.matrix);
  igtl_image_convert_byte_order(&ih);
  std::memcpy(body, &ih, kImageHeaderBytes);
  std::memcpy(body + kImageHeaderBytes, volume.voxels().data(), volume.voxel_count());

  const std::span<const std::uint8_t> body_span(body, kImageHeaderBytes + volume.voxel_count());
  igtl_header h{};
  h.version = IGTL_HEADER_VERSION;
  std::strncpy(h.name, "IMAGE", IGTL_HEADER_TYPE_SIZE);
  std::memcpy(h.device_name, options.device_name.data(), options.device_name.size());
  h.timestamp = SecondsToIgtlTimestamp(volume.timestamp_s());
  h.body_size = body_span.size();
  h.crc = options.libigtl_crc ? Crc64Ecma182LibIgtl(body_span) : Crc64Ecma182(body_span);
  igtl_header_convert_byte_order(&h);
  std::memcpy(out.data(), &h, kHeaderBytes);
}

void WriteMessageHeader(const std::string& type, const std::string& device_name, double timestamp_s,
                        std::span<const std::uint8_t> body, std::uint8_t* out) {
  const auto check = [](const std::string& name, std::size_t max, const char* what) {
    if (name.size() > max) {
      throw std::invalid_argument("OpenIGTLink " + std::string(what) + " '" + name +
                                  "' is longer than " + std::to_string(max) + " bytes");
    }
    for (const char ch : name) {
      const auto c = static_cast<unsigned char>(ch);
      if (c < 0x20 || c > 0x7E) {
        throw std::invalid_argument("OpenIGTLink " + std::string(what) + " '" + name +
                                    "' has a byte that is not printable ASCII");
      }
    }
  };
  check(type, IGTL_HEADER_TYPE_SIZE, "message type");
  check(device_name, IGTL_HEADER_NAME_SIZE, "device name");
  if (type.empty()) throw std::invalid_argument("OpenIGTLink message type is empty");
  igtl_header h{};
  h.version = IGTL_HEADER_VERSION;
  std::memcpy(h.name, type.data(), type.size());
  std::memcpy(h.device_name, device_name.data(), device_name.size());
  h.timestamp = SecondsToIgtlTimestamp(timestamp_s);
  h.body_size = body.size();
  h.crc = Crc64Ecma182(body);
  igtl_header_convert_byte_order(&h);
  std::memcpy(out, &h, kHeaderBytes);
}

std::vector<std::uint8_t> EncodeImage(const Volume& volume, const EncodeOptions& options) {
  std::vector<std::uint8_t> out;
  EncodeImage(volume, options, out);
  return out;
}

std::vector<std::uint8_t> EncodeImageLibIgtl(const Volume& volume, const EncodeOptions& options) {
  CheckEncodable(volume, options);
  const VolumeGeometry& g = volume.geometry();
  auto msg = ::igtl::ImageMessage::New();
  msg->SetDeviceName(options.device_name.c_str());
  const std::uint64_t ts = SecondsToIgtlTimestamp(volume.timestamp_s());
  msg->SetTimeStamp(static_cast<unsigned int>(ts >> 32),
                    static_cast<unsigned int>(ts & 0xFFFFFFFFULL));
  msg->SetDimensions(g.dims.x(), g.dims.y(), g.dims.z());
  msg->SetScalarType(::igtl::ImageMessage::TYPE_UINT8);
  msg->SetNumComponents(1);
  msg->SetEndian(::igtl::ImageMessage::ENDIAN_LITTLE);
  msg->SetCoordinateSystem(options.coordinate_system == CoordinateSystem::kRas
                               ? ::igtl::ImageMessage::COORDINATE_RAS
                               : ::igtl::ImageMessage::COORDINATE_LPS);
  msg->SetSpacing(static_cast<float>(g.spacing_mm.x()), static_cast<float>(g.spacing_mm.y()),
                  static_cast<float>(g.spacing_mm.z()));
  const auto m = ImageMatrix(g, options.coordinate_system);
  float t[3], s[3], n[3];
  for (int r = 0; r < 3; ++r) {
    t[r] = static_cast<float>(m[r] / g.spacing_mm.x());
    s[r] = static_cast<float>(m[3 + r] / g.spacing_mm.y());
    n[r] = static_cast<float>(m[6 + r] / g.spacing_mm.z());
  }
  msg->SetNormals(t, s, n);
  msg->SetOrigin(m[9], m[10], m[11]);
  msg->AllocateScalars();
  std::memcpy(msg->GetScalarPointer(), volume.voxels().data(), volume.voxel_count());
  msg->Pack();
  const auto* p = static_cast<const std::uint8_t*>(msg->GetPackPointer());
  return std::vector<std::uint8_t>(p, p + msg->GetPackSize());
}

double WallClockSeconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace echoservo::imaging::openigtlink
