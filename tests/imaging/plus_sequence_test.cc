// PLUS sequence metafiles: the real files in data/plus (both syntaxes, tracker-only logs,
// status quirks), exact write/read round trips, Volume conversion, OpenRecording, and
// corrupt files (truncation, flipped compressed bytes, lying DimSize/CompressedDataSize).
#include "imaging/io/plus_sequence.h"

#include <gtest/gtest.h>

#include <fstream>

#include "imaging/io/recording.h"
#include "imaging/io/volume_io.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/file_bytes.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::imaging {
namespace {

using testing::ExpectContains;
using testing::InvalidArgumentMessage;
namespace fs = std::filesystem;

const fs::path kData = fs::path(ECHOSERVO_DATA_DIR) / "plus";

using echoservo::testing::Slurp;
using echoservo::testing::Spit;

void ExpectSameSequence(const PlusSequence& a, const PlusSequence& b) {
  EXPECT_EQ(a.frame_dims, b.frame_dims);
  EXPECT_EQ(a.volume_frames, b.volume_frames);
  EXPECT_EQ(a.element_type, b.element_type);
  EXPECT_EQ(a.spacing_mm, b.spacing_mm);
  EXPECT_EQ(a.origin_mm, b.origin_mm);
  EXPECT_EQ(a.direction, b.direction);
  ASSERT_EQ(a.frames.size(), b.frames.size());
  for (std::size_t i = 0; i < a.frames.size(); ++i)
    EXPECT_EQ(a.frames[i].fields, b.frames[i].fields) << i;
  EXPECT_TRUE(a.pixels == b.pixels);
}

TEST(PlusSequence, NwirePhantomBothSyntaxesAgree) {
  const auto mha = ReadPlusSequence(kData / "NwirePhantomFreehand.igs.mha");
  const auto nrrd = ReadPlusSequence(kData / "NwirePhantomFreehand.igs.nrrd");
  ASSERT_EQ(mha.frames.size(), 97u);
  EXPECT_EQ(mha.frame_dims, (std::array<int, 3>{820, 616, 1}));
  EXPECT_TRUE(mha.compressed);
  EXPECT_TRUE(nrrd.compressed);
  ExpectSameSequence(mha, nrrd);
  const auto& f0 = mha.frames[0];
  EXPECT_DOUBLE_EQ(*f0.Timestamp(), 345.627957);
  EXPECT_TRUE(f0.TransformValid("ProbeToTracker"));
  EXPECT_FALSE(f0.TransformValid("StylusToTrackerTransform"));
  EXPECT_EQ(*f0.TransformStatus("StylusToTracker"), "INVALID");
  EXPECT_DOUBLE_EQ((*f0.Transform("ProbeToTrackerTransform"))(0, 3), -190.886);
  EXPECT_EQ(*f0.ImageStatus(), "OK");
  EXPECT_EQ(*mha.HeaderField("UltrasoundImageOrientation"), "MFA");
}

TEST(PlusSequence, SpinePhantomFreehand) {
  const auto s = ReadPlusSequence(kData / "SpinePhantomFreehand.igs.mha");
  EXPECT_EQ(s.frames.size(), 21u);
  EXPECT_EQ(s.pixels.size(), 820u * 616u * 21u);
  const auto v = SequenceToVolumes(s);
  ASSERT_EQ(v.size(), 21u);
  EXPECT_EQ(v[3].dims(), Eigen::Vector3i(820, 616, 1));
  EXPECT_DOUBLE_EQ(v[0].timestamp_s(), 215.102186);
}

TEST(PlusSequence, TrackerOnlyFiles) {
  const auto s =
      ReadPlusSequence(kData / "WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha");
  EXPECT_EQ(s.frames.size(), 801u);
  EXPECT_EQ(s.frame_dims, (std::array<int, 3>{0, 0, 0}));
  EXPECT_EQ(s.element_type, "MET_OTHER");
  EXPECT_TRUE(s.pixels.empty());
  EXPECT_EQ(*s.frames[0].ImageStatus(), "INVALID");
  EXPECT_TRUE(s.frames[800].TransformValid("ReferenceToTracker"));
  const double t0 = *s.frames.front().Timestamp(), t1 = *s.frames.back().Timestamp();
  EXPECT_NEAR(800.0 / (t1 - t0), 39.0, 2.0);
  ExpectContains(InvalidArgumentMessage([&] {
                   OpenRecording(kData / "WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha");
                 }),
                 "tracker-only");
}

TEST(PlusSequence, StatusQuirks) {
  const auto interp = ReadPlusSequence(kData / "TransformInterpolationTest.igs.mha");
  ASSERT_EQ(interp.frames.size(), 500u);
  // A key with no status counts as OK; ReferenceToTracker has no status field either.
  EXPECT_EQ(*interp.frames[0].TransformStatus("ReferenceToTracker"), "OK");
  EXPECT_FALSE(interp.frames[0].Field("ReferenceToTrackerTransformStatus"));
  EXPECT_TRUE(interp.frames[0].Field("Stylus"));
  bool saw_invalid = false;
  for (const auto& f : interp.frames)
    saw_invalid = saw_invalid || !f.TransformValid("ProbeToTracker");
  EXPECT_TRUE(saw_invalid);
  EXPECT_EQ(*interp.frames[7].TransformStatus("ProbeToTracker"), "INVALID");

  const auto prostate = ReadPlusSequence(kData / "Prostate10_tracker.igs.mha");
  ASSERT_EQ(prostate.frames.size(), 10u);
  EXPECT_EQ(*prostate.frames[0].TransformStatus("ToolToTracker"), "OK");  // "OK " in the file
  EXPECT_TRUE(prostate.frames[0].TransformValid("ToolToTracker"));

  const auto ts = ReadPlusSequence(kData / "TimestampFilteringTest.igs.mha");
  ASSERT_EQ(ts.frames.size(), 500u);
  EXPECT_DOUBLE_EQ(*ts.frames[0].Timestamp(), 1840749.750288);  // Timestamp wins
  EXPECT_EQ(*ts.frames[0].Field("UnfilteredTimestamp"), "1840749.051000");
}

TEST(PlusSequence, WriteReadRoundTripsExactly) {
  testing::TempDir dir("plusseq", true);
  for (const char* name : {"NwirePhantomFreehand.igs.mha", "TransformInterpolationTest.igs.mha",
                           "WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha"}) {
    const auto s = ReadPlusSequence(kData / name);
    for (bool compress : {true, false}) {
      for (const char* ext : {".igs.mha", ".igs.nrrd"}) {
        const fs::path out = dir.path() / (std::string("out") + (compress ? "z" : "r") + ext);
        WritePlusSequence(s, out, compress);
        const auto back = ReadPlusSequence(out);
        SCOPED_TRACE(std::string(name) + " -> " + out.string());
        ExpectSameSequence(s, back);
        EXPECT_EQ(back.header_fields, s.header_fields);
      }
    }
  }
}

TEST(PlusSequence, VolumesRoundTripThroughA3DSequence) {
  testing::TempDir dir("plusseq", true);
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(6, 5, 4);
  g.spacing_mm = Eigen::Vector3d(0.5, 0.25, 0.7);
  g.origin_mm = Eigen::Vector3d(1.5, -2.25, 3.1);
  g.direction = Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  std::vector<Volume> vols;
  for (int i = 0; i < 3; ++i) {
    Volume v = Volume::Create(g, static_cast<std::uint8_t>(10 * i));
    v.at(1, 2, 3) = 200;
    v.set_timestamp_s(12.5 + 0.05 * i);
    v.set_frame_index(100 + i);
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.linear() =
        Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
    p.translation() = Eigen::Vector3d(1, 2, 3 + i);
    v.set_probe_to_reference(p);
    v.set_image_to_probe(p.inverse());
    vols.push_back(std::move(v));
  }
  const fs::path out = dir.path() / "vols.igs.mha";
  WritePlusSequence(VolumesToSequence(vols), out, true);
  const auto seq = ReadPlusSequence(out);
  EXPECT_TRUE(seq.volume_frames);
  EXPECT_NE(Slurp(out).find("NDims = 4"), std::string::npos);
  auto source = OpenRecording(out);
  EXPECT_NEAR(source->nominal_rate_hz(), 20.0, 1e-9);
  for (int i = 0; i < 3; ++i) {
    auto f = source->Next();
    ASSERT_TRUE(f);
    const Volume& v = f->volume;
    EXPECT_EQ(v.dims(), g.dims);
    EXPECT_EQ(v.spacing_mm(), g.spacing_mm);
    EXPECT_EQ(v.origin_mm(), g.origin_mm);
    EXPECT_EQ(v.direction(), g.direction);
    EXPECT_EQ(v.timestamp_s(), vols[static_cast<std::size_t>(i)].timestamp_s());
    EXPECT_EQ(v.frame_index(), 100 + i);
    EXPECT_TRUE(v.probe_to_reference().matrix() ==
                vols[static_cast<std::size_t>(i)].probe_to_reference().matrix());
    EXPECT_TRUE(v.image_to_probe().matrix() ==
                vols[static_cast<std::size_t>(i)].image_to_probe().matrix());
    EXPECT_TRUE(std::equal(v.voxels().begin(), v.voxels().end(),
                           vols[static_cast<std::size_t>(i)].voxels().begin()));
  }
  EXPECT_FALSE(source->Next());
}

TEST(OpenRecording, SingleVolumeAndFolder) {
  testing::TempDir dir("plusseq", true);
  auto one = OpenRecording(kData / "SpinePhantomFreehandReconstructed.mha");
  auto f = one->Next();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->volume.dims(), Eigen::Vector3i(147, 106, 104));
  EXPECT_FALSE(one->Next());
  const Volume v = f->volume;
  WriteVolume(v, dir.path() / "b.vti");
  WriteVolume(v, dir.path() / "a.mha");
  Spit(dir.path() / "notes.txt", "ignored");
  auto folder = OpenRecording(dir.path());
  int n = 0;
  while (auto fr = folder->Next()) {
    EXPECT_EQ(fr->volume.frame_index(), n);
    EXPECT_EQ(fr->volume.dims(), v.dims());
    ++n;
  }
  EXPECT_EQ(n, 2);
  ExpectContains(InvalidArgumentMessage([&] { OpenRecording(dir.path() / "missing"); }),
                 "no such file");
}

class CorruptSequence : public ::testing::Test {
 protected:
  testing::TempDir dir{"plusseq", true};
  std::string text = Slurp(kData / "SpinePhantomFreehand.igs.mha");
  std::string Error(const std::string& contents) {
    const fs::path p = dir.path() / "bad.igs.mha";
    Spit(p, contents);
    const auto msg = InvalidArgumentMessage([&] { ReadPlusSequence(p); });
    ExpectContains(msg, "bad.igs.mha");
    return msg;
  }
};

TEST_F(CorruptSequence, Truncated) {
  ExpectContains(Error(text.substr(0, text.size() / 2)), "CompressedDataSize");
  ExpectContains(Error(text.substr(0, 3000)), "ElementDataFile");
}

TEST_F(CorruptSequence, FlippedCompressedBytes) {
  std::string t = text;
  for (std::size_t i = t.size() / 2; i < t.size() / 2 + 64; ++i)
    t[i] = static_cast<char>(t[i] ^ 0xA5);
  ExpectContains(Error(t), "corrupt compressed data");
}

TEST_F(CorruptSequence, LyingDimSize) {
  std::string t = text;
  t.replace(t.find("DimSize = 820 616 21"), 20, "DimSize = 820 616 22");
  ExpectContains(Error(t), "bytes");
  t = text;
  t.replace(t.find("DimSize = 820 616 21"), 20, "DimSize = 820 616 20");
  ExpectContains(Error(t), "frame 20");
  t = text;
  t.replace(t.find("DimSize = 820 616 21"), 20, "DimSize = 99999999 99999 21");
  ExpectContains(Error(t), "4 GiB");
  t = text;
  t.replace(t.find("DimSize = 820 616 21"), 20, "DimSize = 820 6x6 21");
  ExpectContains(Error(t), "6x6");
}

TEST_F(CorruptSequence, LyingCompressedDataSize) {
  std::string t = text;
  t.replace(t.find("CompressedDataSize = 3466024"), 28, "CompressedDataSize = 9466024");
  ExpectContains(Error(t), "CompressedDataSize");
  t = text;
  t.replace(t.find("CompressedDataSize = 3466024"), 28, "CompressedDataSize = 1466024");
  ExpectContains(Error(t), "truncated compressed stream");
}

TEST_F(CorruptSequence, BadNumbersInFields) {
  auto s = ReadPlusSequence(kData / "Prostate10_tracker.igs.mha");
  s.frames[2].fields["ToolToTrackerTransform"] = "1 2 3 nan";
  EXPECT_THROW(s.frames[2].Transform("ToolToTracker"), std::invalid_argument);
  s.frames[2].fields["Timestamp"] = "abc";
  ExpectContains(InvalidArgumentMessage([&] { s.frames[2].Timestamp(); }), "Timestamp");
}

}  // namespace
}  // namespace echoservo::imaging
