// The frame-at-a-time PLUS sequence reader (imaging/io/sequence_reader.h): it gives the same
// volumes as the whole-file reader, streams uncompressed data whatever its total (a sparse
// data file of more than 4 GiB here), reads compressed data whole within the cap, and names
// the file and frame when the data is not there.
#include "imaging/io/sequence_reader.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <string>
#include <vector>

#include "imaging/io/plus_sequence.h"
#include "imaging/io/recording.h"
#include "imaging/io/sequence_writer.h"
#include "tests/imaging/sequence_test_frames.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::imaging {
namespace {

namespace fs = std::filesystem;
using test_frames::ExpectFrame;
using test_frames::Frame;
using testing::ExpectContains;
using testing::InvalidArgumentMessage;

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// A detached MetaImage sequence header of `frames` frames of nx·ny·nz uint8 voxels in `raw`.
std::string DetachedHeader(int nx, int ny, int nz, std::uint64_t frames, const std::string& raw) {
  return "ObjectType = Image\nNDims = 4\nBinaryData = True\nDimSize = " + std::to_string(nx) + " " +
         std::to_string(ny) + " " + std::to_string(nz) + " " + std::to_string(frames) +
         "\nElementSpacing = 0.5 0.5 0.5 1\nElementType = MET_UCHAR\nElementDataFile = " + raw +
         "\n";
}

TEST(SequenceReader, StreamsTheFramesTheWholeFileReaderGives) {
  const testing::TempDir dir("seqr", true);
  const fs::path header = dir.path() / "volumes.igs.mhd";
  {
    SequenceWriter w(header);
    for (int i = 0; i < 6; ++i) w.Append(Frame(i));
  }
  SequenceReader r(header);
  EXPECT_TRUE(r.streamed());
  EXPECT_TRUE(r.sequence().pixels.empty());  // nothing but the header and fields in memory
  ASSERT_EQ(r.size(), 6u);
  const PlusSequence whole = ReadPlusSequence(header);
  // In any order (replay goes forwards; a tuning tool may seek).
  for (int i : {5, 0, 3, 1, 4, 2}) {
    const auto f = static_cast<std::size_t>(i);
    ExpectFrame(r.ReadVolume(f), f, i);
    ExpectFrame(whole, f, i);
  }
  EXPECT_EQ(r.sequence().frames[2].fields, whole.frames[2].fields);
  ExpectContains(InvalidArgumentMessage([&] { r.ReadVolume(6); }), "frame 6: no such frame");
}

TEST(SequenceReader, ReadsCompressedAndLocalSequencesToo) {
  const testing::TempDir dir("seqr", true);
  std::vector<Volume> volumes;
  for (int i = 0; i < 4; ++i) volumes.push_back(Frame(i));
  const PlusSequence seq = VolumesToSequence(volumes);
  for (const bool compress : {true, false}) {
    const fs::path path = dir.path() / (compress ? "z.igs.mha" : "raw.igs.mha");
    WritePlusSequence(seq, path, compress);
    SequenceReader r(path);
    EXPECT_EQ(r.streamed(), !compress) << path;  // LOCAL raw data is streamed from after the header
    ASSERT_EQ(r.size(), 4u);
    for (std::size_t f = 0; f < 4; ++f) ExpectFrame(r.ReadVolume(f), f, static_cast<int>(f));
  }
}

// 16 400 frames of 64³ voxels: 4.3 GB, past the whole-file readers' 4 GiB cap. The data file
// is sparse (zeros but for a marker in the last frame), so the test costs no disk.
TEST(SequenceReader, ASequenceLargerThanTheWholeFileCapIsReadFrameByFrame) {
  const testing::TempDir dir("seqr", true);
  constexpr int kN = 64;
  constexpr std::uint64_t kFrames = 16400, kFrameBytes = kN * kN * kN;
  static_assert(kFrames * kFrameBytes > (4ULL << 30));
  const fs::path header = dir.path() / "long.igs.mhd", raw = dir.path() / "long.igs.raw";
  WriteText(header, DetachedHeader(kN, kN, kN, kFrames, "long.igs.raw"));
  {
    std::ofstream out(raw, std::ios::binary);
    out.seekp(static_cast<std::streamoff>((kFrames - 1) * kFrameBytes + 12345));
    out.put(static_cast<char>(0xab));
  }
  fs::resize_file(raw, kFrames * kFrameBytes);
  ExpectContains(InvalidArgumentMessage([&] { ReadPlusSequence(header); }), "exceed the 4 GiB cap");
  SequenceReader r(header);
  ASSERT_TRUE(r.streamed());
  ASSERT_EQ(r.size(), kFrames);
  const Volume last = r.ReadVolume(kFrames - 1);
  EXPECT_EQ(last.voxels()[12345], 0xab);
  EXPECT_EQ(last.voxels()[12344], 0);
  EXPECT_EQ(last.frame_index(), static_cast<std::int64_t>(kFrames - 1));
  EXPECT_EQ(r.ReadVolume(0).voxels()[12345], 0);
  // OpenRecording (track --replay) takes it the same way.
  auto source = OpenRecording(header);
  ASSERT_TRUE(source->Next().has_value());
}

TEST(SequenceReader, DataMissingOrTooManyFramesAreErrorsNamingTheFile) {
  const testing::TempDir dir("seqr", true);
  const fs::path header = dir.path() / "v.igs.mhd", raw = dir.path() / "v.igs.raw";
  {
    SequenceWriter w(header);
    for (int i = 0; i < 3; ++i) w.Append(Frame(i));
  }
  const auto frame_bytes = Frame(0).voxels().size();
  // Short at open: the header declares more than the file holds.
  fs::resize_file(raw, 3 * frame_bytes - 1);
  ExpectContains(InvalidArgumentMessage([&] { SequenceReader r(header); }), header.string());
  // Shrunk after opening: the frames still there read, the one gone is an error naming it.
  fs::resize_file(raw, 3 * frame_bytes);
  SequenceReader r(header);
  fs::resize_file(raw, frame_bytes + frame_bytes / 2);
  ExpectFrame(r.ReadVolume(0), 0, 0);
  const std::string msg = InvalidArgumentMessage([&] { r.ReadVolume(2); });
  ExpectContains(msg, raw.string());
  ExpectContains(msg, "frame 2");
  ExpectContains(msg, "shrunk");
  // A header declaring more frames than a sequence may have, each of 1 voxel (the data is
  // there: a sparse file), is refused before anything per frame is allocated.
  const fs::path many = dir.path() / "many.igs.mhd";
  const std::uint64_t too_many = (1ULL << 20) + 1;
  WriteText(many, DetachedHeader(1, 1, 1, too_many, "many.raw"));
  std::ofstream(dir.path() / "many.raw").close();
  fs::resize_file(dir.path() / "many.raw", too_many);
  for (auto read : {+[](const fs::path& p) { SequenceReader x(p); },
                    +[](const fs::path& p) { ReadPlusSequence(p); }}) {
    const std::string m = InvalidArgumentMessage([&] { read(many); });
    ExpectContains(m, many.string());
    ExpectContains(m, "1048576");
  }
}

TEST(SequenceReader, MissingDataFileNamesTheHeaderAndTheElementDataFile) {
  const testing::TempDir dir("seqr", true);
  const fs::path header = dir.path() / "gone.igs.mhd";
  WriteText(header, DetachedHeader(2, 2, 2, 3, "gone.igs.raw"));
  const std::string where = fs::absolute(dir.path()).lexically_normal().string();
  for (auto read : {+[](const fs::path& p) { SequenceReader x(p); },
                    +[](const fs::path& p) { ReadPlusSequence(p); },
                    +[](const fs::path& p) { OpenRecording(p); }}) {
    const std::string m = InvalidArgumentMessage([&] { read(header); });
    ExpectContains(m, header.string() + ": ElementDataFile 'gone.igs.raw' not found (looked in " +
                          where + ")");
  }
}

}  // namespace
}  // namespace echoservo::imaging
