// ReadVolume / WriteVolume: exact round trips (.mha compressed and raw, .mhd, .vti), the
// real PLUS reconstructed volume, and clear errors for corrupt or unsupported files.
#include "imaging/io/volume_io.h"

#include <gtest/gtest.h>

#include <fstream>

#include "tests/test_util/expect_error.h"
#include "tests/test_util/file_bytes.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::imaging {
namespace {

using testing::ExpectContains;
using testing::InvalidArgumentMessage;
namespace fs = std::filesystem;

const fs::path kPlusData = fs::path(ECHOSERVO_DATA_DIR) / "plus";

Volume MakeVolume() {
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(7, 5, 3);
  g.spacing_mm = Eigen::Vector3d(0.3, 0.41, 1.0 / 3.0);
  g.origin_mm = Eigen::Vector3d(-12.345678901234, 0.1, 7.0 / 9.0);
  g.direction = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  Volume v = Volume::Create(g);
  int n = 0;
  for (auto& x : v.voxels()) x = static_cast<std::uint8_t>((n++ * 37) % 256);
  return v;
}

void ExpectSameVolume(const Volume& a, const Volume& b) {
  EXPECT_EQ(a.dims(), b.dims());
  EXPECT_EQ(a.spacing_mm(), b.spacing_mm());
  EXPECT_EQ(a.origin_mm(), b.origin_mm());
  EXPECT_EQ(a.direction(), b.direction());
  ASSERT_EQ(a.voxels().size(), b.voxels().size());
  EXPECT_TRUE(std::equal(a.voxels().begin(), a.voxels().end(), b.voxels().begin()));
}

class VolumeRoundTrip : public ::testing::TestWithParam<std::pair<std::string, bool>> {};

TEST_P(VolumeRoundTrip, IsExact) {
  testing::TempDir dir("volio", true);
  const Volume v = MakeVolume();
  const fs::path file = dir.path() / ("v" + GetParam().first);
  WriteVolume(v, file, {.compress = GetParam().second});
  ExpectSameVolume(v, ReadVolume(file));
  if (file.extension() != ".vti") {
    EXPECT_EQ(InspectVolumeFile(file).compressed, GetParam().second);
    EXPECT_EQ(InspectVolumeFile(file).element_type, "MET_UCHAR");
  }
}

INSTANTIATE_TEST_SUITE_P(Formats, VolumeRoundTrip,
                         ::testing::Values(std::pair<std::string, bool>{".mha", true},
                                           std::pair<std::string, bool>{".mha", false},
                                           std::pair<std::string, bool>{".mhd", true},
                                           std::pair<std::string, bool>{".mhd", false},
                                           std::pair<std::string, bool>{".vti", true},
                                           std::pair<std::string, bool>{".vti", false}));

TEST(ReadVolume, RealReconstructedVolume) {
  const Volume v = ReadVolume(kPlusData / "SpinePhantomFreehandReconstructed.mha");
  EXPECT_EQ(v.dims(), Eigen::Vector3i(147, 106, 104));
  EXPECT_EQ(v.spacing_mm(), Eigen::Vector3d(0.5, 0.5, 0.5));
  EXPECT_EQ(v.origin_mm(), Eigen::Vector3d(-74.5217, 165.573, 29.072));
  EXPECT_TRUE(v.direction().isIdentity());
  int nonzero = 0;
  for (auto x : v.voxels()) nonzero += x != 0;
  EXPECT_GT(nonzero, 1000);
}

using echoservo::testing::Slurp;
using echoservo::testing::Spit;

TEST(ReadVolume, CorruptFilesGiveClearErrors) {
  testing::TempDir dir("volio", true);
  const fs::path good = dir.path() / "good.mha";
  WriteVolume(MakeVolume(), good, {.compress = false});
  const std::string text = Slurp(good);

  const fs::path truncated = dir.path() / "trunc.mha";
  Spit(truncated, text.substr(0, text.size() - 10));
  auto msg = InvalidArgumentMessage([&] { ReadVolume(truncated); });
  ExpectContains(msg, "trunc.mha");
  ExpectContains(msg, "truncated");

  const fs::path lie = dir.path() / "lie.mha";
  std::string t = text;
  t.replace(t.find("DimSize = 7 5 3"), 15, "DimSize = 4000 4000 4000");
  Spit(lie, t);
  msg = InvalidArgumentMessage([&] { ReadVolume(lie); });
  ExpectContains(msg, "lie.mha");
  ExpectContains(msg, "DimSize");

  const fs::path ushort = dir.path() / "short.mha";
  t = text;
  t.replace(t.find("MET_UCHAR"), 9, "MET_SHORT");
  Spit(ushort, t);
  ExpectContains(InvalidArgumentMessage([&] { ReadVolume(ushort); }), "MET_SHORT");

  const fs::path zgood = dir.path() / "z.mha";
  WriteVolume(MakeVolume(), zgood, {.compress = true});
  std::string z = Slurp(zgood);
  z[z.size() - 20] ^= 0x5a;
  z[z.size() - 21] ^= 0x5a;
  const fs::path flipped = dir.path() / "flipped.mha";
  Spit(flipped, z);
  msg = InvalidArgumentMessage([&] { ReadVolume(flipped); });
  ExpectContains(msg, "flipped.mha");

  ExpectContains(InvalidArgumentMessage([&] { ReadVolume(dir.path() / "none.mha"); }),
                 "no such file");
  ExpectContains(InvalidArgumentMessage([&] { ReadVolume(dir.path() / "x.png"); }), "extension");
  const fs::path garbage = dir.path() / "garbage.vti";
  Spit(garbage, "not xml at all");
  ExpectContains(InvalidArgumentMessage([&] { ReadVolume(garbage); }), "garbage.vti");
}

// A detached header whose pixel file is missing: the error names the header, the
// ElementDataFile it points to and where it was looked for (not only the .raw); a sequence
// header the same (SequenceReader, OpenRecording and `info` read it the same way).
TEST(ReadVolume, MissingDataFileNamesTheHeaderAndTheElementDataFile) {
  testing::TempDir dir("volio", true);
  const fs::path header = dir.path() / "x.mhd";
  WriteVolume(MakeVolume(), header, {.compress = false});
  ASSERT_TRUE(fs::exists(dir.path() / "x.raw"));
  fs::remove(dir.path() / "x.raw");
  const std::string msg = InvalidArgumentMessage([&] { ReadVolume(header); });
  ExpectContains(msg, header.string() + ": ElementDataFile 'x.raw' not found (looked in " +
                          fs::absolute(dir.path()).lexically_normal().string() + ")");
  ExpectContains(InvalidArgumentMessage([&] { InspectVolumeFile(header); }), "x.mhd");

  // A data file that is a folder is named as such.
  fs::create_directory(dir.path() / "x.raw");
  ExpectContains(InvalidArgumentMessage([&] { ReadVolume(header); }),
                 "x.mhd: ElementDataFile 'x.raw' (");
  ExpectContains(InvalidArgumentMessage([&] { ReadVolume(header); }), "not a regular file");
}

}  // namespace
}  // namespace echoservo::imaging
