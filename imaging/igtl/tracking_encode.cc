// Encoders of TRANSFORM, TDATA, POINT and STATUS (tracking_messages.h): bodies written field
// by field in big-endian order, the header by WriteMessageHeader (image_message.h).
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "imaging/igtl/tracking_messages.h"

namespace echoservo::imaging::openigtlink {
// Helpers in their own namespace: the library is built as unity batches, beside the decoders.
namespace tracking_encode_internal {
namespace {

// Largest |RᵀR − I| element an encoder accepts: float32 round-off of a rotation read back
// from a file or a message is ~1e-7; a scaled or sheared matrix is far beyond.
constexpr double kRigidTolerance = 1e-5;

class BodyWriter {
 public:
  explicit BodyWriter(std::uint8_t* p) : p_(p) {}
  void U8(std::uint8_t v) { *p_++ = v; }
  void U16(std::uint16_t v) {
    U8(static_cast<std::uint8_t>(v >> 8));
    U8(static_cast<std::uint8_t>(v));
  }
  void U32(std::uint32_t v) {
    for (int s = 24; s >= 0; s -= 8) U8(static_cast<std::uint8_t>(v >> s));
  }
  void U64(std::uint64_t v) {
    for (int s = 56; s >= 0; s -= 8) U8(static_cast<std::uint8_t>(v >> s));
  }
  void F32(double v) { U32(std::bit_cast<std::uint32_t>(static_cast<float>(v))); }
  // `text` into a NUL-padded field of `size` bytes (checked by CheckName beforehand).
  void Name(const std::string& text, std::size_t size) {
    std::memset(p_, 0, size);
    std::memcpy(p_, text.data(), text.size());
    p_ += size;
  }
  void Bytes(const void* data, std::size_t n) {
    std::memcpy(p_, data, n);
    p_ += n;
  }

 private:
  std::uint8_t* p_;
};

void CheckName(const std::string& text, std::size_t max_bytes, const std::string& what) {
  if (text.size() > max_bytes) {
    throw std::invalid_argument(what + " '" + text + "' is longer than " +
                                std::to_string(max_bytes) + " bytes");
  }
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c > 0x7E) {
      throw std::invalid_argument(what + " '" + text + "' has a byte that is not printable ASCII");
    }
  }
}

// Finite, and within float32's range (the wire's type; converting beyond it is undefined).
void CheckFinite(double v, const std::string& what) {
  if (!std::isfinite(v)) throw std::invalid_argument(what + " is not finite");
  if (std::abs(v) > std::numeric_limits<float>::max()) {
    throw std::invalid_argument(what + " " + std::to_string(v) + " is beyond float32's range");
  }
}

void CheckRigid(const Eigen::Isometry3d& t, const std::string& what) {
  const Eigen::Matrix4d& m = t.matrix();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) CheckFinite(m(r, c), what + ": matrix element");
  }
  const Eigen::Matrix3d rot = t.linear();
  const double err = (rot.transpose() * rot - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(err <= kRigidTolerance) || !(rot.determinant() > 0.0)) {
    throw std::invalid_argument(what +
                                ": rotation is not rigid (|RᵀR − I| = " + std::to_string(err) +
                                ", det " + std::to_string(rot.determinant()) + ")");
  }
}

// The 12 floats of a TRANSFORM body or TDATA element: rotation column by column, then the
// translation.
void WriteMatrix(BodyWriter& w, const Eigen::Isometry3d& t) {
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) w.F32(t.linear()(r, c));
  }
  for (int r = 0; r < 3; ++r) w.F32(t.translation()[r]);
}

// Checks the device name before anything is written (WriteMessageHeader checks it again).
void CheckDevice(const std::string& type, const std::string& device_name) {
  CheckName(device_name, 20, "OpenIGTLink " + type + " device name");
}

}  // namespace
}  // namespace tracking_encode_internal

void EncodeTransform(const std::string& device_name, double timestamp_s,
                     const Eigen::Isometry3d& transform, std::vector<std::uint8_t>& out) {
  using namespace tracking_encode_internal;
  CheckDevice("TRANSFORM", device_name);
  CheckRigid(transform, "OpenIGTLink TRANSFORM '" + device_name + "'");
  out.resize(kHeaderBytes + kTransformBodyBytes);
  BodyWriter w(out.data() + kHeaderBytes);
  WriteMatrix(w, transform);
  WriteMessageHeader("TRANSFORM", device_name, timestamp_s,
                     std::span<const std::uint8_t>(out).subspan(kHeaderBytes), out.data());
}

void EncodeTrackingData(const std::string& device_name, double timestamp_s,
                        const std::vector<TrackedTransform>& elements,
                        std::vector<std::uint8_t>& out) {
  using namespace tracking_encode_internal;
  CheckDevice("TDATA", device_name);
  if (elements.empty()) {
    throw std::invalid_argument("OpenIGTLink TDATA '" + device_name + "': no element");
  }
  for (const TrackedTransform& e : elements) {
    const std::string what = "OpenIGTLink TDATA '" + device_name + "' element '" + e.name + "'";
    CheckName(e.name, 20, what + ": name");
    CheckRigid(e.transform, what);
  }
  out.resize(kHeaderBytes + kTdataElementBytes * elements.size());
  BodyWriter w(out.data() + kHeaderBytes);
  for (const TrackedTransform& e : elements) {
    w.Name(e.name, 20);
    w.U8(e.tdata_type == 0 ? 2 : e.tdata_type);  // 0 (a TRANSFORM's): a 6D tool
    w.U8(0);                                     // reserved
    WriteMatrix(w, e.transform);
  }
  WriteMessageHeader("TDATA", device_name, timestamp_s,
                     std::span<const std::uint8_t>(out).subspan(kHeaderBytes), out.data());
}

void EncodePoints(const std::string& device_name, double timestamp_s,
                  const std::vector<IgtlPoint>& points, std::vector<std::uint8_t>& out) {
  using namespace tracking_encode_internal;
  CheckDevice("POINT", device_name);
  if (points.empty()) {
    throw std::invalid_argument("OpenIGTLink POINT '" + device_name + "': no point");
  }
  for (const IgtlPoint& p : points) {
    const std::string what = "OpenIGTLink POINT '" + device_name + "' point '" + p.name + "'";
    CheckName(p.name, 63, what + ": name");
    CheckName(p.group, 31, what + ": group");
    CheckName(p.owner, 19, what + ": owner");
    for (int i = 0; i < 3; ++i) CheckFinite(p.position_mm[i], what + ": position");
    CheckFinite(p.radius_mm, what + ": radius");
  }
  out.resize(kHeaderBytes + kPointElementBytes * points.size());
  BodyWriter w(out.data() + kHeaderBytes);
  for (const IgtlPoint& p : points) {
    w.Name(p.name, 64);
    w.Name(p.group, 32);
    w.Bytes(p.rgba.data(), 4);
    for (int i = 0; i < 3; ++i) w.F32(p.position_mm[i]);
    w.F32(p.radius_mm);
    w.Name(p.owner, 20);
  }
  WriteMessageHeader("POINT", device_name, timestamp_s,
                     std::span<const std::uint8_t>(out).subspan(kHeaderBytes), out.data());
}

void EncodeStatus(const std::string& device_name, double timestamp_s, const IgtlStatus& status,
                  std::vector<std::uint8_t>& out) {
  using namespace tracking_encode_internal;
  CheckDevice("STATUS", device_name);
  const std::string what = "OpenIGTLink STATUS '" + device_name + "'";
  if (status.code > 19) {
    throw std::invalid_argument(what + ": code " + std::to_string(status.code) +
                                " is beyond the protocol's 0..19");
  }
  CheckName(status.error_name, 19, what + ": error name");
  if (status.message.find('\0') != std::string::npos) {
    throw std::invalid_argument(what + ": message contains a NUL byte");
  }
  out.resize(kHeaderBytes + kStatusFixedBytes + status.message.size() + 1);
  BodyWriter w(out.data() + kHeaderBytes);
  w.U16(status.code);
  w.U64(static_cast<std::uint64_t>(status.subcode));
  w.Name(status.error_name, 20);
  w.Bytes(status.message.data(), status.message.size());
  w.U8(0);
  WriteMessageHeader("STATUS", device_name, timestamp_s,
                     std::span<const std::uint8_t>(out).subspan(kHeaderBytes), out.data());
}

Eigen::Isometry3d CatheterFrame(const Eigen::Vector3d& tip_mm, const Eigen::Vector3d& axis) {
  using namespace tracking_encode_internal;
  if (!tip_mm.allFinite() || !axis.allFinite()) {
    throw std::invalid_argument("CatheterFrame: tip or axis is not finite");
  }
  const double norm = axis.norm();
  if (!(norm > 1e-12)) throw std::invalid_argument("CatheterFrame: the axis is zero");
  const Eigen::Vector3d z = axis / norm;
  int least = 0;  // the image axis least aligned with z (lowest index on ties)
  for (int i = 1; i < 3; ++i) {
    if (std::abs(z[i]) < std::abs(z[least])) least = i;
  }
  const Eigen::Vector3d e = Eigen::Vector3d::Unit(least);
  const Eigen::Vector3d x = (e - e.dot(z) * z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.linear().col(0) = x;
  frame.linear().col(1) = y;
  frame.linear().col(2) = z;
  frame.translation() = tip_mm;
  return frame;
}

}  // namespace echoservo::imaging::openigtlink
