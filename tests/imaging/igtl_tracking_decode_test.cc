// The TRANSFORM, TDATA, POINT and STATUS decoders (imaging/igtl/tracking_messages.h) on the
// OpenIGTLink repository's reference messages (data/openigtlink, values from its
// Testing/igtlutil test data), on messages packed by libOpenIGTLink's own classes (a codec
// that shares no code with ours), and on each bad input of issue 19, every rejection with
// its reason.
#include <gtest/gtest.h>
#include <igtlPointMessage.h>
#include <igtlStatusMessage.h>
#include <igtlTimeStamp.h>
#include <igtlTrackingDataMessage.h>
#include <igtlTransformMessage.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "imaging/igtl/tracking_messages.h"
#include "tests/imaging/igtl_test_bytes.h"

namespace echoservo::imaging::openigtlink::tracking_decode_test {
namespace {

const std::filesystem::path kRefDir = std::filesystem::path(ECHOSERVO_DATA_DIR) / "openigtlink";

std::vector<std::uint8_t> ReadRef(const std::string& name) {
  std::ifstream in(kRefDir / name, std::ios::binary);
  EXPECT_TRUE(in) << name;
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct Split {
  MessageHeader header;
  std::span<const std::uint8_t> body;
};

// Header + body of a whole message; the header's body_size must match the bytes.
Split SplitMessage(const std::vector<std::uint8_t>& m) {
  Split s;
  s.header = ParseHeader(m, DecodeLimits{});
  EXPECT_EQ(s.header.body_size + kHeaderBytes, m.size());
  s.body = std::span<const std::uint8_t>(m).subspan(kHeaderBytes);
  return s;
}

// The reference matrix of OpenIGTLink's test data (igtl_test_data_transform.h): rotation
// columns and translation, as documented in data/SOURCES.md for the IMAGE of the same tests.
const double kRefMatrix[12] = {-0.954892, 0.196632, -0.222525,  -0.196632, 0.142857, 0.970014,
                               0.222525,  0.970014, -0.0977491, 46.0531,   19.4709,  46.0531};
constexpr std::uint64_t kRefTimestampRaw = 1234567892;  // data/SOURCES.md

void ExpectReferencePose(const Eigen::Isometry3d& t, const std::string& what) {
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      EXPECT_NEAR(t.linear()(r, c), kRefMatrix[3 * c + r], 2e-6) << what << " R" << r << c;
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(t.translation()[k], kRefMatrix[9 + k], 1e-4) << what << " t" << k;
}

template <typename F>
std::string Reason(F decode) {
  try {
    decode();
  } catch (const MessageError& e) {
    return e.reason();
  }
  return "accepted";
}

// libOpenIGTLink's bytes of a packed message.
std::vector<std::uint8_t> Packed(igtl::MessageBase* m) {
  m->Pack();
  const auto* p = static_cast<const std::uint8_t*>(m->GetPackPointer());
  return {p, p + m->GetPackSize()};
}

igtl::TimeStamp::Pointer Stamp(double t_s) {
  igtl::TimeStamp::Pointer ts = igtl::TimeStamp::New();
  ts->SetTime(t_s);
  return ts;
}

// A libOpenIGTLink TRANSFORM of `pose` (columns of the rotation, then the translation).
std::vector<std::uint8_t> LibTransform(const std::string& name, double t_s,
                                       const Eigen::Matrix4d& pose) {
  igtl::TransformMessage::Pointer msg = igtl::TransformMessage::New();
  msg->SetDeviceName(name.c_str());
  igtl::Matrix4x4 m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[r][c] = static_cast<float>(pose(r, c));
  msg->SetMatrix(m);
  auto ts = Stamp(t_s);
  msg->SetTimeStamp(ts);
  return Packed(msg.GetPointer());
}

Eigen::Matrix4d RandomPose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized().toRotationMatrix();
  t.translation() = 200.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
  return t.matrix();
}

TEST(IgtlTrackingDecode, ReferenceTransformV1AndV2DecodeToTheDocumentedPose) {
  for (const char* file : {"test_transform_message.bin", "test_transform_message_Format2.bin"}) {
    const auto m = ReadRef(file);
    const Split s = SplitMessage(m);
    EXPECT_NO_THROW(CheckBodyCrc(s.header, s.body)) << file;
    const TrackedTransform t = DecodeTransform(s.header, s.body);
    EXPECT_EQ(t.name, "DeviceName") << file;
    EXPECT_EQ(t.tdata_type, 0);
    EXPECT_FALSE(t.orthonormalized) << file << ": float32 round-off only";
    EXPECT_EQ(s.header.timestamp, kRefTimestampRaw);  // the raw 32.32 field
    ExpectReferencePose(t.transform, file);
  }
  // Format2 (header version 2): its metadata, as OpenIGTLink's test writes it.
  const auto m = ReadRef("test_transform_message_Format2.bin");
  const Split s = SplitMessage(m);
  const auto meta = DecodeMetadata(s.header, s.body);
  ASSERT_EQ(meta.size(), 2u);
  EXPECT_EQ(meta[0], (std::pair<std::string, std::string>{"First patient age", "22"}));
  EXPECT_EQ(meta[1], (std::pair<std::string, std::string>{"Second patient age", "25"}));
  const auto v1 = ReadRef("test_transform_message.bin");
  EXPECT_TRUE(DecodeMetadata(SplitMessage(v1).header, SplitMessage(v1).body).empty());
}

TEST(IgtlTrackingDecode, ReferenceTdataPointAndStatusDecodeToTheirValues) {
  for (const char* file : {"test_tdata_message.bin", "test_tdata_messageFormat2.bin"}) {
    const auto m = ReadRef(file);
    const Split s = SplitMessage(m);
    EXPECT_NO_THROW(CheckBodyCrc(s.header, s.body));
    const auto e = DecodeTrackingData(s.header, s.body);
    ASSERT_EQ(e.size(), 3u) << file;
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(e[i].name, "Tracker" + std::to_string(i)) << file;
      EXPECT_EQ(e[i].tdata_type, 2) << file;  // 6D
      ExpectReferencePose(e[i].transform, file);
    }
  }
  {
    const auto m = ReadRef("test_point_message.bin");
    const Split s = SplitMessage(m);
    EXPECT_NO_THROW(CheckBodyCrc(s.header, s.body));
    const auto p = DecodePoints(s.header, s.body);
    ASSERT_EQ(p.size(), 3u);
    const std::array<std::uint8_t, 4> rgba[3] = {
        {255, 0, 0, 255}, {0, 255, 0, 255}, {0, 0, 255, 255}};
    const Eigen::Vector3d pos[3] = {{10, 15, 20}, {25, 30, 35}, {40, 45, 50}};
    const double radius[3] = {5, 3, 1};
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(p[i].name, "POINT_DESCRIPTION_" + std::to_string(i));
      EXPECT_EQ(p[i].group, "Landmark");
      EXPECT_EQ(p[i].owner, "IMAGE_0");
      EXPECT_EQ(p[i].rgba, rgba[i]);
      EXPECT_EQ(p[i].position_mm, pos[i]);  // exact in float32
      EXPECT_EQ(p[i].radius_mm, radius[i]);
    }
  }
  {
    const auto m = ReadRef("test_status_message.bin");
    const Split s = SplitMessage(m);
    EXPECT_NO_THROW(CheckBodyCrc(s.header, s.body));
    const IgtlStatus st = DecodeStatus(s.header, s.body);
    EXPECT_EQ(st.code, static_cast<std::uint16_t>(StatusCode::kDisabled));
    EXPECT_EQ(st.subcode, 10);
    EXPECT_EQ(st.error_name, "ACTUATOR_DISABLED");
    EXPECT_EQ(st.message, "Actuator A is disabled.");
  }
}

TEST(IgtlTrackingDecode, MessagesPackedByLibOpenIGTLinkDecodeToWhatWasPacked) {
  std::mt19937 rng(19);
  for (int n = 0; n < 20; ++n) {
    const Eigen::Matrix4d pose = RandomPose(rng);
    const double t_s = 1.7e9 + 0.025 * n;
    const auto m = LibTransform("CatheterTipToTracker", t_s, pose);
    const Split s = SplitMessage(m);
    EXPECT_NO_THROW(CheckBodyCrc(s.header, s.body));
    const TrackedTransform t = DecodeTransform(s.header, s.body);
    EXPECT_EQ(t.name, "CatheterTipToTracker");
    // float32 on the wire: 6e-8 relative; 200 mm → 2e-5 mm.
    EXPECT_LT((t.transform.matrix() - pose).cwiseAbs().maxCoeff(), 3e-5) << n;
    EXPECT_NEAR(s.header.timestamp_s(), t_s, 2e-6) << n;  // libigtl keeps nanoseconds
  }
  {
    igtl::TrackingDataMessage::Pointer msg = igtl::TrackingDataMessage::New();
    msg->SetDeviceName("Tracker");
    Eigen::Matrix4d poses[2] = {RandomPose(rng), RandomPose(rng)};
    const char* names[2] = {"ProbeToTracker", "CatheterTipToTracker"};
    for (int i = 0; i < 2; ++i) {
      igtl::TrackingDataElement::Pointer e = igtl::TrackingDataElement::New();
      e->SetName(names[i]);
      e->SetType(igtl::TrackingDataElement::TYPE_6D);
      igtl::Matrix4x4 mm;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) mm[r][c] = static_cast<float>(poses[i](r, c));
      e->SetMatrix(mm);
      msg->AddTrackingDataElement(e);
    }
    const auto m = Packed(msg.GetPointer());
    const Split s = SplitMessage(m);
    const auto e = DecodeTrackingData(s.header, s.body);
    ASSERT_EQ(e.size(), 2u);
    for (int i = 0; i < 2; ++i) {
      EXPECT_EQ(e[i].name, names[i]);
      EXPECT_EQ(e[i].tdata_type, 2);
      EXPECT_LT((e[i].transform.matrix() - poses[i]).cwiseAbs().maxCoeff(), 3e-5);
    }
  }
  {
    igtl::PointMessage::Pointer msg = igtl::PointMessage::New();
    msg->SetDeviceName("echoservo");
    igtl::PointElement::Pointer e = igtl::PointElement::New();
    e->SetName("tip");
    e->SetGroupName("Catheter");
    e->SetRGBA(10, 20, 30, 40);
    e->SetPosition(-12.5f, 3.25f, 80.0f);
    e->SetRadius(1.5f);
    e->SetOwner("Image");
    msg->AddPointElement(e);
    const auto m = Packed(msg.GetPointer());
    const Split s = SplitMessage(m);
    const auto p = DecodePoints(s.header, s.body);
    ASSERT_EQ(p.size(), 1u);
    EXPECT_EQ(p[0].name, "tip");
    EXPECT_EQ(p[0].group, "Catheter");
    EXPECT_EQ(p[0].owner, "Image");
    EXPECT_EQ(p[0].rgba, (std::array<std::uint8_t, 4>{10, 20, 30, 40}));
    EXPECT_EQ(p[0].position_mm, Eigen::Vector3d(-12.5, 3.25, 80.0));
    EXPECT_EQ(p[0].radius_mm, 1.5);
  }
  {
    igtl::StatusMessage::Pointer msg = igtl::StatusMessage::New();
    msg->SetDeviceName("echoservo");
    msg->SetCode(igtl::StatusMessage::STATUS_NOT_FOUND);
    msg->SetSubCode(-3);
    msg->SetErrorName("CatheterLost");
    msg->SetStatusString("no catheter in volume 12");
    const auto m = Packed(msg.GetPointer());
    const Split s = SplitMessage(m);
    const IgtlStatus st = DecodeStatus(s.header, s.body);
    EXPECT_EQ(st.code, static_cast<std::uint16_t>(StatusCode::kNotFound));
    EXPECT_EQ(st.subcode, -3);
    EXPECT_EQ(st.error_name, "CatheterLost");
    EXPECT_EQ(st.message, "no catheter in volume 12");
  }
}

TEST(IgtlTrackingDecode, SmallRotationErrorsAreReorthonormalisedAndSaidSo) {
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  pose.block<3, 3>(0, 0) =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  pose.block<3, 1>(0, 0) *= 1.0002;  // 4e-4 on RᵀR: inside the 1e-3 tolerance
  pose.block<3, 1>(0, 3) = Eigen::Vector3d(1, 2, 3);
  const auto m = LibTransform("T", 1.0, pose);
  const Split s = SplitMessage(m);
  const TrackedTransform t = DecodeTransform(s.header, s.body);
  EXPECT_TRUE(t.orthonormalized);
  const Eigen::Matrix3d r = t.transform.linear();
  EXPECT_LT((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  EXPECT_LT((r - pose.block<3, 3>(0, 0)).cwiseAbs().maxCoeff(), 3e-4);
}

TEST(IgtlTrackingDecode, EachBadInputIsRejectedWithItsReason) {
  using testing::Recrc;
  const Eigen::Matrix4d good = [] {
    Eigen::Matrix4d p = Eigen::Matrix4d::Identity();
    p.block<3, 3>(0, 0) = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    p.block<3, 1>(0, 3) = Eigen::Vector3d(10, 20, 30);
    return p;
  }();
  auto transform_reason = [](const std::vector<std::uint8_t>& m) {
    return Reason([&] {
      const Split s = SplitMessage(m);
      CheckBodyCrc(s.header, s.body);
      DecodeTransform(s.header, s.body);
    });
  };
  EXPECT_EQ(transform_reason(LibTransform("T", 5.0, good)), "accepted");

  Eigen::Matrix4d sheared = good;
  sheared(0, 1) += 0.05;  // columns no longer orthogonal
  EXPECT_EQ(transform_reason(LibTransform("T", 5.0, sheared)), "non_orthonormal");
  Eigen::Matrix4d scaled = good;
  scaled.block<3, 3>(0, 0) *= 1.01;  // a unit error (mm vs cm, …)
  EXPECT_EQ(transform_reason(LibTransform("T", 5.0, scaled)), "non_orthonormal");
  Eigen::Matrix4d mirrored = good;
  mirrored.block<3, 1>(0, 2) *= -1.0;  // a reflection: orthonormal but det −1
  EXPECT_EQ(transform_reason(LibTransform("T", 5.0, mirrored)), "non_orthonormal");
  Eigen::Matrix4d nan = good;
  nan(1, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(transform_reason(LibTransform("T", 5.0, nan)), "non_finite");
  Eigen::Matrix4d inf = good;
  inf(2, 2) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(transform_reason(LibTransform("T", 5.0, inf)), "non_finite");
  Eigen::Matrix4d far = good;
  far(0, 3) = 2e5;  // 200 m
  EXPECT_EQ(transform_reason(LibTransform("T", 5.0, far)), "out_of_range");

  // Wrong body size: a TRANSFORM of 44 and of 52 bytes (CRC and size consistent).
  {
    auto m = LibTransform("T", 5.0, good);
    m.resize(m.size() - 4);
    testing::PutBigEndian64(m, 42, kTransformBodyBytes - 4);
    Recrc(m);
    EXPECT_EQ(transform_reason(m), "bad_body_size");
    m.resize(m.size() + 8, 0);
    testing::PutBigEndian64(m, 42, kTransformBodyBytes + 4);
    Recrc(m);
    EXPECT_EQ(transform_reason(m), "bad_body_size");
  }
  // A body span that is not what the header announces (a framing bug in a caller).
  {
    const auto m = LibTransform("T", 5.0, good);
    const Split s = SplitMessage(m);
    EXPECT_EQ(Reason([&] { DecodeTransform(s.header, s.body.first(40)); }), "bad_body_size");
  }
  // Bad CRC: one body bit flipped.
  {
    auto m = LibTransform("T", 5.0, good);
    m[kHeaderBytes + 7] ^= 0x10;
    EXPECT_EQ(transform_reason(m), "bad_crc");
  }
  // Wrong type to a decoder.
  {
    const auto m = LibTransform("T", 5.0, good);
    const Split s = SplitMessage(m);
    EXPECT_EQ(Reason([&] { DecodeTrackingData(s.header, s.body); }), "wrong_type");
    EXPECT_EQ(Reason([&] { DecodeStatus(s.header, s.body); }), "wrong_type");
    EXPECT_EQ(Reason([&] { DecodePoints(s.header, s.body); }), "wrong_type");
  }
  // TDATA: not a whole number of elements, none, a bad element name.
  {
    auto m = ReadRef("test_tdata_message.bin");
    auto cut = m;
    cut.resize(cut.size() - 1);
    testing::PutBigEndian64(cut, 42, cut.size() - kHeaderBytes);
    Recrc(cut);
    const Split s1 = SplitMessage(cut);
    EXPECT_EQ(Reason([&] { DecodeTrackingData(s1.header, s1.body); }), "bad_body_size");
    auto none = std::vector<std::uint8_t>(m.begin(), m.begin() + kHeaderBytes);
    testing::PutBigEndian64(none, 42, 0);
    Recrc(none);
    const Split s0 = SplitMessage(none);
    EXPECT_EQ(Reason([&] { DecodeTrackingData(s0.header, s0.body); }), "bad_body_size");
    auto named = m;
    named[kHeaderBytes + 70 + 3] = 0x07;  // a control character in element 1's name
    Recrc(named);
    const Split s2 = SplitMessage(named);
    EXPECT_EQ(Reason([&] { DecodeTrackingData(s2.header, s2.body); }), "bad_name");
    auto trailing = m;
    trailing[kHeaderBytes + 15] = 'x';  // a byte after element 0's NUL padding
    Recrc(trailing);
    const Split s3 = SplitMessage(trailing);
    EXPECT_EQ(Reason([&] { DecodeTrackingData(s3.header, s3.body); }), "bad_name");
    TrackingDecodeLimits two;
    two.max_elements = 2;
    const Split s4 = SplitMessage(m);
    EXPECT_EQ(Reason([&] { DecodeTrackingData(s4.header, s4.body, two); }), "bad_body_size");
  }
  // STATUS: a code beyond 19, a message without its NUL, a body shorter than 30 bytes.
  {
    const auto m = ReadRef("test_status_message.bin");
    auto code = m;
    code[kHeaderBytes] = 0;
    code[kHeaderBytes + 1] = 20;
    Recrc(code);
    const Split s1 = SplitMessage(code);
    EXPECT_EQ(Reason([&] { DecodeStatus(s1.header, s1.body); }), "bad_status");
    auto unterminated = m;
    unterminated.back() = '!';
    Recrc(unterminated);
    const Split s2 = SplitMessage(unterminated);
    EXPECT_EQ(Reason([&] { DecodeStatus(s2.header, s2.body); }), "bad_status");
    auto shorter = std::vector<std::uint8_t>(m.begin(), m.begin() + kHeaderBytes + 29);
    testing::PutBigEndian64(shorter, 42, 29);
    Recrc(shorter);
    const Split s3 = SplitMessage(shorter);
    EXPECT_EQ(Reason([&] { DecodeStatus(s3.header, s3.body); }), "bad_body_size");
  }
  // POINT: NaN position, negative radius, an element not whole.
  {
    const auto m = ReadRef("test_point_message.bin");
    auto nanp = m;
    const std::uint32_t qnan = 0x7fc00000;
    for (int b = 0; b < 4; ++b)
      nanp[kHeaderBytes + 64 + 32 + 4 + b] = static_cast<std::uint8_t>(qnan >> (24 - 8 * b));
    Recrc(nanp);
    const Split s1 = SplitMessage(nanp);
    EXPECT_EQ(Reason([&] { DecodePoints(s1.header, s1.body); }), "non_finite");
    auto negative = m;
    negative[kHeaderBytes + 64 + 32 + 16] |= 0x80;  // the radius' sign bit
    Recrc(negative);
    const Split s2 = SplitMessage(negative);
    EXPECT_EQ(Reason([&] { DecodePoints(s2.header, s2.body); }), "out_of_range");
  }
  // Header version 2 with an extended header that does not fit.
  {
    auto m = ReadRef("test_transform_message_Format2.bin");
    m[kHeaderBytes + 4] = 0x7f;  // metadata size ≈ 2 GB
    Recrc(m);
    const Split s = SplitMessage(m);
    EXPECT_EQ(Reason([&] { DecodeTransform(s.header, s.body); }), "bad_extended_header");
    EXPECT_EQ(Reason([&] { DecodeMetadata(s.header, s.body); }), "bad_extended_header");
    auto tiny = ReadRef("test_transform_message_Format2.bin");
    tiny[kHeaderBytes + 1] = 4;  // a 4-byte extended header
    Recrc(tiny);
    const Split s2 = SplitMessage(tiny);
    EXPECT_EQ(Reason([&] { DecodeTransform(s2.header, s2.body); }), "bad_extended_header");
  }
}

// Truncated, bit-flipped and resized reference messages: the decoders either accept or
// throw MessageError, never anything else (the fuzz target does this at scale).
TEST(IgtlTrackingDecode, MutatedReferenceMessagesOnlyEverThrowMessageError) {
  std::mt19937 rng(1919);
  const char* files[] = {"test_transform_message.bin", "test_transform_message_Format2.bin",
                         "test_tdata_message.bin",     "test_tdata_messageFormat2.bin",
                         "test_point_message.bin",     "test_status_message.bin"};
  int accepted = 0, rejected = 0;
  for (const char* file : files) {
    const auto ref = ReadRef(file);
    for (int n = 0; n < 300; ++n) {
      auto m = ref;
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int f = 0; f < flips; ++f) {
        const std::size_t at = kHeaderBytes + rng() % (m.size() - kHeaderBytes);
        m[at] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
      }
      if (rng() % 3 == 0) {
        m.resize(kHeaderBytes + rng() % (m.size() - kHeaderBytes + 1));
        testing::PutBigEndian64(m, 42, m.size() - kHeaderBytes);
      }
      testing::Recrc(m);
      const MessageHeader h = ParseHeader(m, DecodeLimits{});
      const std::span<const std::uint8_t> body(m.data() + kHeaderBytes, m.size() - kHeaderBytes);
      try {
        if (h.type == "TRANSFORM") DecodeTransform(h, body);
        if (h.type == "TDATA") DecodeTrackingData(h, body);
        if (h.type == "POINT") DecodePoints(h, body);
        if (h.type == "STATUS") DecodeStatus(h, body);
        DecodeMetadata(h, body);
        ++accepted;
      } catch (const MessageError&) {
        ++rejected;
      }
    }
  }
  EXPECT_GT(rejected, 0);
  EXPECT_GT(accepted, 0);  // flips in values (not names or sizes) decode
}

}  // namespace
}  // namespace echoservo::imaging::openigtlink::tracking_decode_test
