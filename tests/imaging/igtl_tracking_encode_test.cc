// Conformance of the TRANSFORM, TDATA, POINT and STATUS encoders (tracking_messages.h):
// encoding the values libOpenIGTLink's own test messages hold (data/openigtlink, written by
// libOpenIGTLink's test suite) reproduces them byte for byte, and libOpenIGTLink's message
// classes (a peer that shares no code with ours) unpack our bytes, CRC checked, to our values.
// Encoder errors: names too long, non-finite values, non-rigid rotations. CatheterFrame.
#include <gtest/gtest.h>
#include <igtlMessageHeader.h>
#include <igtlPointMessage.h>
#include <igtlStatusMessage.h>
#include <igtlTrackingDataMessage.h>
#include <igtlTransformMessage.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>

#include "imaging/igtl/tracking_messages.h"

namespace echoservo::imaging::openigtlink {
namespace tracking_encode_test {
namespace {

const std::filesystem::path kRefDir = std::filesystem::path(ECHOSERVO_DATA_DIR) / "openigtlink";

std::vector<std::uint8_t> ReadBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << path;
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The values of libOpenIGTLink's testing/igtl_*_test.c (the messages in data/openigtlink):
// device "DeviceName", raw timestamp 1234567892 (in the fraction field: 1234567892 / 2³² s),
// this 3×4 matrix (rotation columns, then
// translation) for TRANSFORM and each TDATA element.
constexpr double kRefTimestampS = 1234567892.0 / 4294967296.0;
const std::string kRefDevice = "DeviceName";
constexpr float kRefMatrix[12] = {-0.954892f,  0.196632f, -0.222525f, -0.196632f,
                                  0.142857f,   0.970014f, 0.222525f,  0.970014f,
                                  -0.0977491f, 46.0531f,  19.4709f,   46.0531f};

Eigen::Isometry3d RefTransform() {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) t.linear()(r, c) = kRefMatrix[3 * c + r];
  }
  for (int r = 0; r < 3; ++r) t.translation()[r] = kRefMatrix[9 + r];
  return t;
}

// Unpacks `bytes` with libOpenIGTLink: the header through igtl::MessageHeader, the body into
// `message` with the CRC checked. Returns false when libOpenIGTLink refuses it.
bool UnpackWithLibIgtl(const std::vector<std::uint8_t>& bytes, igtl::MessageBase* message) {
  if (bytes.size() < kHeaderBytes) return false;
  igtl::MessageHeader::Pointer header = igtl::MessageHeader::New();
  header->InitPack();
  std::memcpy(header->GetPackPointer(), bytes.data(), kHeaderBytes);
  header->Unpack();
  if (static_cast<std::size_t>(header->GetBodySizeToRead()) != bytes.size() - kHeaderBytes) {
    return false;
  }
  message->SetMessageHeader(header);
  message->AllocatePack();
  std::memcpy(message->GetPackBodyPointer(), bytes.data() + kHeaderBytes,
              bytes.size() - kHeaderBytes);
  const int status = message->Unpack(1);
  return (status & igtl::MessageHeader::UNPACK_BODY) != 0;
}

double LibIgtlTimestamp(igtl::MessageBase* message) {
  unsigned int sec = 0, frac = 0;
  message->GetTimeStamp(&sec, &frac);
  return static_cast<double>(sec) + static_cast<double>(frac) / 4294967296.0;
}

// Byte-for-byte equality, reporting the first difference (offset, both bytes) and sizes.
void ExpectSameBytes(const std::vector<std::uint8_t>& ours, const std::vector<std::uint8_t>& ref) {
  EXPECT_EQ(ours.size(), ref.size());
  for (std::size_t i = 0; i < std::min(ours.size(), ref.size()); ++i) {
    if (ours[i] != ref[i]) {
      ADD_FAILURE() << "first difference at byte " << i << ": ours " << int{ours[i]}
                    << ", reference " << int{ref[i]};
      return;
    }
  }
}

// Rotation ≈ the tolerance of float32 (relative 6e-8) on unit values; translations in mm of
// ~100 round to 4e-6 mm.
constexpr double kFloatTol = 1e-6;

TEST(IgtlTrackingEncode, TransformMatchesReferenceBytes) {
  std::vector<std::uint8_t> ours;
  EncodeTransform(kRefDevice, kRefTimestampS, RefTransform(), ours);
  ExpectSameBytes(ours, ReadBytes(kRefDir / "test_transform_message.bin"));
}

TEST(IgtlTrackingEncode, TrackingDataMatchesReferenceBytes) {
  std::vector<TrackedTransform> elements(3);
  for (int i = 0; i < 3; ++i) {
    elements[i].name = "Tracker" + std::to_string(i);
    elements[i].tdata_type = 2;  // 6D
    elements[i].transform = RefTransform();
  }
  std::vector<std::uint8_t> ours;
  EncodeTrackingData(kRefDevice, kRefTimestampS, elements, ours);
  ExpectSameBytes(ours, ReadBytes(kRefDir / "test_tdata_message.bin"));
}

TEST(IgtlTrackingEncode, PointsMatchReferenceBytes) {
  const std::array<std::array<std::uint8_t, 4>, 3> rgba{
      {{255, 0, 0, 255}, {0, 255, 0, 255}, {0, 0, 255, 255}}};
  const double radius[3] = {5.0, 3.0, 1.0};
  std::vector<IgtlPoint> points(3);
  for (int i = 0; i < 3; ++i) {
    points[i].name = "POINT_DESCRIPTION_" + std::to_string(i);
    points[i].group = "Landmark";
    points[i].rgba = rgba[i];
    points[i].position_mm = Eigen::Vector3d(10.0 + 15 * i, 15.0 + 15 * i, 20.0 + 15 * i);
    points[i].radius_mm = radius[i];
    points[i].owner = "IMAGE_0";
  }
  std::vector<std::uint8_t> ours;
  EncodePoints(kRefDevice, kRefTimestampS, points, ours);
  ExpectSameBytes(ours, ReadBytes(kRefDir / "test_point_message.bin"));
}

TEST(IgtlTrackingEncode, StatusMatchesReferenceBytes) {
  IgtlStatus status;
  status.code = static_cast<std::uint16_t>(StatusCode::kDisabled);
  status.subcode = 10;
  status.error_name = "ACTUATOR_DISABLED";
  status.message = "Actuator A is disabled.";
  std::vector<std::uint8_t> ours;
  EncodeStatus(kRefDevice, kRefTimestampS, status, ours);
  ExpectSameBytes(ours, ReadBytes(kRefDir / "test_status_message.bin"));
}

TEST(IgtlTrackingEncode, LibIgtlUnpacksOurTransform) {
  // A rotation that is not the reference's, a fractional timestamp, a PLUS-style name.
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(-12.25, 40.5, 101.75);
  const double stamp = 1790000000.123456;
  std::vector<std::uint8_t> ours;
  EncodeTransform("CatheterToImage", stamp, t, ours);
  igtl::TransformMessage::Pointer msg = igtl::TransformMessage::New();
  ASSERT_TRUE(UnpackWithLibIgtl(ours, msg.GetPointer()));
  EXPECT_STREQ(msg->GetDeviceName(), "CatheterToImage");
  EXPECT_STREQ(msg->GetDeviceType(), "TRANSFORM");
  EXPECT_NEAR(LibIgtlTimestamp(msg.GetPointer()), stamp, 1e-6);  // 32.32: 2.3e-10 s steps
  igtl::Matrix4x4 m;
  msg->GetMatrix(m);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(m[r][c], t.linear()(r, c), kFloatTol);
    EXPECT_NEAR(m[r][3], t.translation()[r], 1e-5);
  }
}

TEST(IgtlTrackingEncode, LibIgtlUnpacksOurTrackingData) {
  std::vector<TrackedTransform> elements(2);
  elements[0].name = "StylusTipToTracker";
  elements[0].transform.translation() = Eigen::Vector3d(1, 2, 3);
  elements[1].name = "ProbeToTracker";
  elements[1].tdata_type = 4;  // 5D
  elements[1].transform.linear() =
      Eigen::AngleAxisd(-1.2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  elements[1].transform.translation() = Eigen::Vector3d(-50, 0.5, 250);
  std::vector<std::uint8_t> ours;
  EncodeTrackingData("Tracker", 1000.5, elements, ours);
  ASSERT_EQ(ours.size(), kHeaderBytes + 2 * kTdataElementBytes);
  igtl::TrackingDataMessage::Pointer msg = igtl::TrackingDataMessage::New();
  ASSERT_TRUE(UnpackWithLibIgtl(ours, msg.GetPointer()));
  EXPECT_DOUBLE_EQ(LibIgtlTimestamp(msg.GetPointer()), 1000.5);
  ASSERT_EQ(msg->GetNumberOfTrackingDataElements(), 2);
  for (int i = 0; i < 2; ++i) {
    igtl::TrackingDataElement::Pointer e;
    msg->GetTrackingDataElement(i, e);
    EXPECT_EQ(std::string(e->GetName()), elements[i].name);
    EXPECT_EQ(e->GetType(), i == 0 ? 2 : 4);
    igtl::Matrix4x4 m;
    e->GetMatrix(m);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(m[r][c], elements[i].transform.linear()(r, c), 1e-6);
      EXPECT_NEAR(m[r][3], elements[i].transform.translation()[r], 1e-5);
    }
  }
}

TEST(IgtlTrackingEncode, LibIgtlUnpacksOurPointsAndStatus) {
  std::vector<IgtlPoint> points(2);
  points[0].name = "CatheterTip";
  points[0].group = "Detections";
  points[0].rgba = {255, 255, 0, 255};
  points[0].position_mm = Eigen::Vector3d(-3.5, 7.25, 60.125);
  points[0].radius_mm = 1.0;
  points[1].name = "Target";
  points[1].group = "Detections";
  points[1].position_mm = Eigen::Vector3d(4, -5, 80);
  points[1].owner = "Image";
  std::vector<std::uint8_t> ours;
  EncodePoints("Detections", 42.25, points, ours);
  igtl::PointMessage::Pointer pm = igtl::PointMessage::New();
  ASSERT_TRUE(UnpackWithLibIgtl(ours, pm.GetPointer()));
  EXPECT_DOUBLE_EQ(LibIgtlTimestamp(pm.GetPointer()), 42.25);
  ASSERT_EQ(pm->GetNumberOfPointElement(), 2);
  for (int i = 0; i < 2; ++i) {
    igtl::PointElement::Pointer e;
    pm->GetPointElement(i, e);
    EXPECT_EQ(std::string(e->GetName()), points[i].name);
    EXPECT_EQ(std::string(e->GetGroupName()), points[i].group);
    EXPECT_EQ(std::string(e->GetOwner()), points[i].owner);
    igtlUint8 rgba[4];
    e->GetRGBA(rgba);
    for (int k = 0; k < 4; ++k) EXPECT_EQ(rgba[k], points[i].rgba[k]);
    igtlFloat32 p[3];
    e->GetPosition(p);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(p[k], points[i].position_mm[k], 1e-5);
    EXPECT_NEAR(e->GetRadius(), points[i].radius_mm, 1e-6);
  }

  IgtlStatus status;
  status.code = static_cast<std::uint16_t>(StatusCode::kNotFound);
  status.subcode = -7;
  status.error_name = "NOT_DETECTED";
  status.message = "catheter not found in volume 12";
  EncodeStatus("CatheterToImage", 43.0, status, ours);
  igtl::StatusMessage::Pointer sm = igtl::StatusMessage::New();
  ASSERT_TRUE(UnpackWithLibIgtl(ours, sm.GetPointer()));
  EXPECT_EQ(sm->GetCode(), 4);
  EXPECT_EQ(sm->GetSubCode(), -7);
  EXPECT_STREQ(sm->GetErrorName(), "NOT_DETECTED");
  EXPECT_STREQ(sm->GetStatusString(), "catheter not found in volume 12");
}

TEST(IgtlTrackingEncode, CorruptedBodyFailsLibIgtlCrc) {
  // The check above can fail: a flipped body byte makes libOpenIGTLink's CRC check refuse it.
  std::vector<std::uint8_t> ours;
  EncodeTransform("CatheterToImage", 5.0, RefTransform(), ours);
  ours[kHeaderBytes + 3] ^= 0x01;
  igtl::TransformMessage::Pointer msg = igtl::TransformMessage::New();
  EXPECT_FALSE(UnpackWithLibIgtl(ours, msg.GetPointer()));
}

template <typename F>
std::string InvalidArgumentMessage(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no std::invalid_argument)";
}

TEST(IgtlTrackingEncode, RejectsBadInputNamingIt) {
  std::vector<std::uint8_t> out;
  const Eigen::Isometry3d ok = Eigen::Isometry3d::Identity();
  EXPECT_NE(InvalidArgumentMessage([&] {
              EncodeTransform("ThisDeviceNameIsTooLong", 0.0, ok, out);
            }).find("longer than 20"),
            std::string::npos);
  Eigen::Isometry3d nan = ok;
  nan.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(InvalidArgumentMessage([&] { EncodeTransform("A", 0.0, nan, out); }).find("finite"),
            std::string::npos);
  Eigen::Isometry3d scaled = ok;
  scaled.linear() *= 1.01;  // 1 % scale: not a rigid motion
  EXPECT_NE(
      InvalidArgumentMessage([&] { EncodeTransform("A", 0.0, scaled, out); }).find("not rigid"),
      std::string::npos);
  Eigen::Isometry3d mirror = ok;
  mirror.linear()(0, 0) = -1.0;  // orthonormal, but a reflection
  EXPECT_NE(
      InvalidArgumentMessage([&] { EncodeTransform("A", 0.0, mirror, out); }).find("not rigid"),
      std::string::npos);
  EXPECT_THROW(EncodeTransform("A", -1.0, ok, out), std::invalid_argument);  // timestamp
  Eigen::Isometry3d far = ok;
  far.translation().z() = 1e39;  // finite, but no float32 holds it
  EXPECT_NE(InvalidArgumentMessage([&] { EncodeTransform("A", 0.0, far, out); }).find("float32"),
            std::string::npos);

  std::vector<TrackedTransform> tdata(1);
  tdata[0].name = "ElementNameLongerThan20";
  EXPECT_NE(InvalidArgumentMessage([&] {
              EncodeTrackingData("T", 0.0, tdata, out);
            }).find("ElementNameLongerThan20"),
            std::string::npos);
  EXPECT_THROW(EncodeTrackingData("T", 0.0, {}, out), std::invalid_argument);

  std::vector<IgtlPoint> points(1);
  points[0].group = std::string(32, 'g');
  EXPECT_NE(InvalidArgumentMessage([&] { EncodePoints("P", 0.0, points, out); }).find("group"),
            std::string::npos);
  points[0].group = "ok";
  points[0].position_mm.y() = std::numeric_limits<double>::infinity();
  EXPECT_NE(InvalidArgumentMessage([&] { EncodePoints("P", 0.0, points, out); }).find("position"),
            std::string::npos);

  IgtlStatus status;
  status.code = 20;
  EXPECT_NE(InvalidArgumentMessage([&] { EncodeStatus("S", 0.0, status, out); }).find("code 20"),
            std::string::npos);
  status.code = 1;
  status.error_name = std::string(20, 'e');
  EXPECT_THROW(EncodeStatus("S", 0.0, status, out), std::invalid_argument);
}

TEST(IgtlTrackingEncode, CatheterFrameIsRightHandedWithZAlongTheAxis) {
  const Eigen::Vector3d tip(10, -20, 55);
  for (const Eigen::Vector3d& axis :
       {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0.3, -0.4, 2.0),
        Eigen::Vector3d(-1, -1, -1)}) {
    const Eigen::Isometry3d f = CatheterFrame(tip, axis);
    EXPECT_LT((f.linear().col(2) - axis.normalized()).norm(), 1e-12);
    EXPECT_LT((f.linear().transpose() * f.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    EXPECT_NEAR(f.linear().determinant(), 1.0, 1e-12);
    EXPECT_EQ(f.translation(), tip);
    // A point 5 mm up the catheter from the tip (towards its base) is at z = −5.
    const Eigen::Vector3d behind = tip - 5.0 * axis.normalized();
    EXPECT_LT(((f.inverse() * behind) - Eigen::Vector3d(0, 0, -5)).norm(), 1e-12);
  }
  // Stable: a small change of the axis moves x by about as much (no flip between volumes).
  const Eigen::Isometry3d a = CatheterFrame(tip, Eigen::Vector3d(0.1, 0.2, 1.0));
  const Eigen::Isometry3d b = CatheterFrame(tip, Eigen::Vector3d(0.1, 0.201, 1.0));
  EXPECT_LT((a.linear().col(0) - b.linear().col(0)).norm(), 0.01);
  EXPECT_THROW(CatheterFrame(tip, Eigen::Vector3d::Zero()), std::invalid_argument);
  EXPECT_THROW(CatheterFrame(tip, Eigen::Vector3d(std::nan(""), 0, 1)), std::invalid_argument);
}

}  // namespace
}  // namespace tracking_encode_test
}  // namespace echoservo::imaging::openigtlink
