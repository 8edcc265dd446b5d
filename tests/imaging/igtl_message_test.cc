// OpenIGTLink codec conformance against the reference messages of the OpenIGTLink
// repository (data/openigtlink, see data/SOURCES.md) and rejection of bad input.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "imaging/igtl/crc64.h"
#include "imaging/igtl/image_message.h"
#include "imaging/igtl/phantom_source.h"
#include "tests/imaging/igtl_test_bytes.h"

namespace echoservo::imaging::openigtlink {
namespace {

const std::filesystem::path kDir = std::filesystem::path(ECHOSERVO_DATA_DIR) / "openigtlink";

std::vector<std::uint8_t> ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in) << path;
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::filesystem::path> ReferenceMessages() {
  std::vector<std::filesystem::path> out;
  for (const auto& e : std::filesystem::directory_iterator(kDir)) {
    const auto name = e.path().filename().string();
    if (name.ends_with("_message.bin") || name.ends_with("Format2.bin")) out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

using testing::PutBigEndian64;
void PutBigEndian16(std::vector<std::uint8_t>& m, std::size_t at, std::uint16_t v) {
  m[at] = static_cast<std::uint8_t>(v >> 8);
  m[at + 1] = static_cast<std::uint8_t>(v);
}
// Recomputes the header CRC after the body was edited.
using testing::Recrc;

std::string RejectionReason(const std::vector<std::uint8_t>& m, const DecodeLimits& limits = {}) {
  try {
    DecodeMessage(m, limits);
  } catch (const MessageError& e) {
    return e.reason();
  }
  return "accepted";
}

Volume SmallVolume() {
  VolumeGeometry g;
  g.dims = {7, 5, 3};
  g.spacing_mm = {0.4, 0.5, 0.75};
  g.origin_mm = {-12.5, 3.25, 40.0};
  g.direction = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  Volume v = Volume::Create(g);
  std::mt19937 rng(7);
  for (auto& x : v.voxels()) x = static_cast<std::uint8_t>(rng());
  v.set_timestamp_s(1700000000.25);
  return v;
}

TEST(IgtlCrc, SliceBy8MatchesLibIgtlOnRandomData) {
  std::mt19937 rng(3);
  std::vector<std::uint8_t> data(5000);
  for (auto& x : data) x = static_cast<std::uint8_t>(rng());
  for (std::size_t n : {0, 1, 7, 8, 9, 15, 16, 17, 63, 64, 1000, 4999, 5000}) {
    std::span<const std::uint8_t> s(data.data(), n);
    EXPECT_EQ(Crc64Ecma182(s), Crc64Ecma182LibIgtl(s)) << n;
  }
  // Incremental use over a split buffer.
  EXPECT_EQ(Crc64Ecma182({data.data() + 13, 4987}, Crc64Ecma182({data.data(), 13})),
            Crc64Ecma182(data));
  // The ECMA-182 check value of "123456789" (non-reflected, init 0, no xorout).
  const std::string check = "123456789";
  EXPECT_EQ(Crc64Ecma182({reinterpret_cast<const std::uint8_t*>(check.data()), check.size()}),
            0x6C40DF5F0B497347ULL);
}

TEST(IgtlCrc, EveryReferenceMessageVerifiesWithBothImplementations) {
  const auto files = ReferenceMessages();
  ASSERT_GE(files.size(), 14u);
  for (const auto& f : files) {
    const auto m = ReadFile(f);
    const MessageHeader h = ParseHeader(m, DecodeLimits{});
    ASSERT_EQ(h.body_size + kHeaderBytes, m.size()) << f;
    EXPECT_EQ(h.timestamp, 1234567892u) << f;
    const std::span<const std::uint8_t> body(m.data() + kHeaderBytes, h.body_size);
    EXPECT_EQ(Crc64Ecma182(body), h.crc) << f;
    EXPECT_EQ(Crc64Ecma182LibIgtl(body), h.crc) << f;
  }
}

TEST(IgtlMessage, NdarrayHeaderPlusBodyIsTheMessage) {
  auto header = ReadFile(kDir / "test_ndarray_message_header.bin");
  const auto body = ReadFile(kDir / "test_ndarray_message_body.bin");
  header.insert(header.end(), body.begin(), body.end());
  EXPECT_EQ(header, ReadFile(kDir / "test_ndarray_message.bin"));
}

TEST(IgtlMessage, ReferenceImageDecodesToTheDocumentedGeometry) {
  const auto m = ReadFile(kDir / "test_image_message.bin");
  const DecodedMessage d = DecodeMessage(m, DecodeLimits{});
  EXPECT_EQ(d.header.type, "IMAGE");
  EXPECT_EQ(d.header.device_name, "DeviceName");
  EXPECT_EQ(d.header.version, 1);
  EXPECT_EQ(d.header.timestamp, 1234567892u);
  EXPECT_DOUBLE_EQ(d.header.timestamp_s(), 1234567892.0 / 4294967296.0);
  ASSERT_TRUE(d.image && d.volume);
  EXPECT_EQ(d.image->coordinate_system, CoordinateSystem::kRas);
  EXPECT_FALSE(d.image->orthonormalized);
  // Documented (RAS): i, j, k unit axes, spacing 1, origin (= centre) below.
  const Eigen::Vector3d i_ras(-0.954892, 0.196632, -0.222525);
  const Eigen::Vector3d j_ras(-0.196632, 0.142857, 0.970014);
  const Eigen::Vector3d k_ras(0.222525, 0.970014, -0.0977491);
  const Eigen::Vector3d center_ras(46.0531, 19.4709, 46.0531);
  EXPECT_TRUE(d.image->center_mm.isApprox(center_ras, 1e-6)) << d.image->center_mm.transpose();
  const Volume& v = *d.volume;
  EXPECT_EQ(v.dims(), Eigen::Vector3i(50, 50, 1));
  EXPECT_TRUE(v.spacing_mm().isApprox(Eigen::Vector3d::Ones(), 1e-6)) << v.spacing_mm().transpose();
  const Eigen::Vector3d lps(-1, -1, 1);  // RAS -> LPS
  EXPECT_LT((v.direction().col(0) - lps.cwiseProduct(i_ras)).norm(), 2e-6);
  EXPECT_LT((v.direction().col(1) - lps.cwiseProduct(j_ras)).norm(), 2e-6);
  EXPECT_LT((v.direction().col(2) - lps.cwiseProduct(k_ras)).norm(), 2e-6);
  // The wire origin is the image centre; voxel (0,0,0) lies 24.5 voxels back along i and j.
  const Eigen::Vector3d expected_origin =
      lps.cwiseProduct(center_ras - 24.5 * i_ras - 24.5 * j_ras);
  EXPECT_LT((v.origin_mm() - expected_origin).norm(), 1e-4) << v.origin_mm().transpose();
  EXPECT_LT((v.IndexToPhysical({24.5, 24.5, 0}) - lps.cwiseProduct(center_ras)).norm(), 1e-4);
  // Voxels: the reference raw image, i fastest.
  const auto raw = ReadFile(kDir / "test_image.bin");
  ASSERT_EQ(raw.size(), v.voxel_count());
  EXPECT_TRUE(std::equal(raw.begin(), raw.end(), v.voxels().begin()));
  EXPECT_DOUBLE_EQ(v.timestamp_s(), d.header.timestamp_s());
}

TEST(IgtlMessage, ReferenceImageReencodesByteIdentically) {
  const auto m = ReadFile(kDir / "test_image_message.bin");
  const DecodedMessage d = DecodeMessage(m, DecodeLimits{});
  EncodeOptions o;
  o.device_name = "DeviceName";
  o.coordinate_system = CoordinateSystem::kRas;
  EXPECT_EQ(EncodeImage(*d.volume, o), m);
  o.libigtl_crc = true;
  EXPECT_EQ(EncodeImage(*d.volume, o), m);
}

TEST(IgtlMessage, NonImageReferenceMessagesAreRecognisedAndSkipped) {
  int non_image = 0;
  for (const auto& f : ReferenceMessages()) {
    if (f.filename() == "test_image_message.bin") continue;
    const auto m = ReadFile(f);
    const DecodedMessage d = DecodeMessage(m, DecodeLimits{});
    EXPECT_NE(d.header.type, "IMAGE") << f;
    EXPECT_FALSE(d.volume.has_value()) << f;
    ++non_image;
  }
  EXPECT_GE(non_image, 13);
}

TEST(IgtlMessage, RoundTripPreservesGeometryVoxelsAndTimeInBothCoordinateSystems) {
  const Volume v = SmallVolume();
  for (const auto cs : {CoordinateSystem::kRas, CoordinateSystem::kLps}) {
    EncodeOptions o;
    o.coordinate_system = cs;
    const auto m = EncodeImage(v, o);
    ASSERT_EQ(m.size(), EncodedImageSize(v));
    const DecodedMessage d = DecodeMessage(m, DecodeLimits{});
    ASSERT_TRUE(d.volume);
    EXPECT_EQ(d.image->coordinate_system, cs);
    EXPECT_EQ(d.volume->dims(), v.dims());
    EXPECT_TRUE(d.volume->spacing_mm().isApprox(v.spacing_mm(), 1e-6));
    EXPECT_LT((d.volume->direction() - v.direction()).cwiseAbs().maxCoeff(), 1e-6);
    EXPECT_LT((d.volume->origin_mm() - v.origin_mm()).norm(), 1e-4);  // float32 on the wire
    EXPECT_TRUE(std::equal(v.voxels().begin(), v.voxels().end(), d.volume->voxels().begin()));
    EXPECT_NEAR(d.volume->timestamp_s(), v.timestamp_s(), 1e-6);
    // Re-encoding the decoded volume gives the same bytes.
    EXPECT_EQ(EncodeImage(*d.volume, o), m);
  }
}

TEST(IgtlMessage, MatchesLibOpenIGTLinkEncoder) {
  const Volume v = SmallVolume();
  const auto mine = EncodeImage(v);
  const auto lib = EncodeImageLibIgtl(v);
  ASSERT_EQ(mine.size(), lib.size());
  // Headers agree up to the CRC; image headers up to float rounding of the matrix
  // (libOpenIGTLink multiplies normal × spacing in float), voxels exactly.
  EXPECT_TRUE(std::equal(mine.begin(), mine.begin() + 50, lib.begin()));
  EXPECT_TRUE(std::equal(mine.begin() + 58 + 72, mine.end(), lib.begin() + 58 + 72));
  const DecodedMessage a = DecodeMessage(mine, DecodeLimits{});
  const DecodedMessage b = DecodeMessage(lib, DecodeLimits{});  // its CRC verifies with ours
  for (int k = 0; k < 12; ++k) EXPECT_NEAR(a.image->matrix[k], b.image->matrix[k], 1e-5) << k;
}

TEST(IgtlMessage, RejectsBadInputWithReasons) {
  const auto good = EncodeImage(SmallVolume());
  EXPECT_EQ(RejectionReason(good), "accepted");

  auto bad_crc = good;
  bad_crc[200] ^= 0x40;
  EXPECT_EQ(RejectionReason(bad_crc), "bad_crc");

  auto size_mismatch = good;  // one voxel fewer than dims promise
  size_mismatch.pop_back();
  PutBigEndian64(size_mismatch, 42, size_mismatch.size() - kHeaderBytes);
  Recrc(size_mismatch);
  EXPECT_EQ(RejectionReason(size_mismatch), "body_size_mismatch");

  auto huge = good;  // 65535^3 voxels announced in a 177-byte body: no allocation may happen
  for (int a = 0; a < 3; ++a) PutBigEndian16(huge, 58 + 6 + 2 * a, 65535);
  Recrc(huge);
  EXPECT_EQ(RejectionReason(huge), "too_many_voxels");
  DecodeLimits tight;
  tight.max_voxels = 100;
  EXPECT_EQ(RejectionReason(good, tight), "too_many_voxels");

  auto scalar = good;
  scalar[58 + 3] = 5;  // uint16
  Recrc(scalar);
  EXPECT_EQ(RejectionReason(scalar), "unsupported_image");

  auto coord = good;
  coord[58 + 5] = 3;
  Recrc(coord);
  EXPECT_EQ(RejectionReason(coord), "bad_coordinate_system");

  auto garbage = good;
  garbage[3] = 0x01;  // control character in the type name
  EXPECT_EQ(RejectionReason(garbage), "bad_header");
  auto version = good;
  version[1] = 9;
  EXPECT_EQ(RejectionReason(version), "bad_header");

  DecodeLimits small_body;
  small_body.max_body_bytes = 100;
  EXPECT_EQ(RejectionReason(good, small_body), "body_too_large");

  auto truncated = good;
  // erase, not resize(size() - 10): GCC 12 at -O1 with ASan warns (-Wstringop-overflow) that
  // the resize could be to SIZE_MAX - 9 and -Werror fails the sanitizer build.
  truncated.erase(truncated.end() - 10, truncated.end());
  EXPECT_EQ(RejectionReason(truncated), "truncated_message");

  auto skewed = good;  // axes far from orthonormal
  const float f = 0.3f;
  std::uint32_t bits;
  std::memcpy(&bits, &f, 4);
  for (int b = 0; b < 4; ++b)
    skewed[58 + 12 + 12 + b] = static_cast<std::uint8_t>(bits >> (24 - 8 * b));
  Recrc(skewed);
  EXPECT_EQ(RejectionReason(skewed), "bad_geometry");
}

TEST(IgtlMessage, TimestampFixedPoint) {
  EXPECT_EQ(SecondsToIgtlTimestamp(0.0), 0u);
  EXPECT_EQ(SecondsToIgtlTimestamp(1.5), (1ULL << 32) | 0x80000000ULL);
  EXPECT_DOUBLE_EQ(IgtlTimestampToSeconds((3ULL << 32) | 0x40000000ULL), 3.25);
  EXPECT_THROW(SecondsToIgtlTimestamp(-1.0), std::invalid_argument);
  EXPECT_THROW(SecondsToIgtlTimestamp(std::nan("")), std::invalid_argument);
}

TEST(IgtlPhantom, FramesAreDeterministicAndMove) {
  PhantomOptions o;
  o.dims = {40, 30, 20};
  o.frame_count = 3;
  PhantomSource a(o), b(o);
  auto a0 = a.Next(), b0 = b.Next(), a1 = a.Next();
  ASSERT_TRUE(a0 && b0 && a1);
  EXPECT_TRUE(std::equal(a0->volume.voxels().begin(), a0->volume.voxels().end(),
                         b0->volume.voxels().begin()));
  EXPECT_FALSE(a0->truth->target_mm.isApprox(a1->truth->target_mm));
  EXPECT_TRUE(a.Next());
  EXPECT_FALSE(a.Next());
}

}  // namespace
}  // namespace echoservo::imaging::openigtlink
