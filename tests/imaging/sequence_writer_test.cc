// The streaming PLUS sequence recorder (imaging/io/sequence_writer.h): what it writes reads
// back exactly with the standard reader, a header always describes only whole frames, and
// a writer killed with SIGKILL at any instant loses at most the volume in flight.
#include "imaging/io/sequence_writer.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <random>

#include "imaging/io/plus_sequence.h"
#include "imaging/io/recording.h"
#include "tests/imaging/sequence_test_frames.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::imaging {
namespace {

namespace fs = std::filesystem;
using test_frames::ExpectFrame;
using test_frames::Frame;
using test_frames::Geometry;
using testing::ExpectContains;
using testing::InvalidArgumentMessage;

TEST(SequenceWriter, WhatItWritesReadsBackExactlyAfterEveryFrame) {
  const testing::TempDir dir("seqw", true);
  const fs::path header = dir.path() / "volumes.igs.mhd";
  SequenceWriter w(header);
  EXPECT_EQ(w.data_path(), dir.path() / "volumes.igs.raw");
  EXPECT_FALSE(fs::exists(header));  // nothing before the first frame
  for (int i = 0; i < 5; ++i) {
    w.Append(Frame(i), {{"Note", "frame" + std::to_string(i)}});
    ASSERT_EQ(w.frames(), static_cast<std::size_t>(i + 1));
    // After every Append the files on disk are a complete sequence of the frames so far.
    const PlusSequence s = ReadPlusSequence(header);
    ASSERT_EQ(s.frames.size(), static_cast<std::size_t>(i + 1));
    EXPECT_TRUE(s.volume_frames);
    for (int f = 0; f <= i; ++f) ExpectFrame(s, static_cast<std::size_t>(f), f);
    EXPECT_EQ(s.frames[static_cast<std::size_t>(i)].Field("Note"), "frame" + std::to_string(i));
  }
  EXPECT_FALSE(fs::exists(dir.path() / "volumes.igs.mhd.tmp"));
  EXPECT_EQ(fs::file_size(w.data_path()), 5 * Frame(0).voxels().size());
  // The recording opens as a volume source, as `track --replay` opens it.
  auto source = OpenRecording(header);
  int n = 0;
  while (auto f = source->Next()) EXPECT_DOUBLE_EQ(f->volume.timestamp_s(), 12.5 + 0.04 * n++);
  EXPECT_EQ(n, 5);
}

TEST(SequenceWriter, DataPastTheFramesTheHeaderListsIsIgnored) {
  // What a kill between the two steps of an Append leaves: the next frame's voxels (here
  // half of them) in the data file, the previous header.
  const testing::TempDir dir("seqw_partial", true);
  const fs::path header = dir.path() / "v.mhd";
  {
    SequenceWriter w(header);
    for (int i = 0; i < 3; ++i) w.Append(Frame(i));
  }
  {
    std::ofstream raw(dir.path() / "v.raw", std::ios::binary | std::ios::app);
    const Volume next = Frame(3);
    raw.write(reinterpret_cast<const char*>(next.voxels().data()),
              static_cast<std::streamsize>(next.voxels().size() / 2));
  }
  const PlusSequence s = ReadPlusSequence(header);
  ASSERT_EQ(s.frames.size(), 3u);
  for (int f = 0; f < 3; ++f) ExpectFrame(s, static_cast<std::size_t>(f), f);
}

TEST(SequenceWriter, BadPathsAndGeometryChangesAreClearErrorsThatKeepTheRecording) {
  const testing::TempDir dir("seqw_bad", true);
  ExpectContains(InvalidArgumentMessage([&] { SequenceWriter w(dir.path() / "v.igs.mha"); }),
                 ".mhd");
  SequenceWriter w(dir.path() / "v.mhd");
  w.Append(Frame(0));
  w.Append(Frame(1));
  const std::string msg = InvalidArgumentMessage([&] { w.Append(Frame(2, Geometry(24, 20, 17))); });
  for (const char* part : {"v.mhd", "frame 2", "geometry"}) ExpectContains(msg, part);
  EXPECT_THROW(w.Append(Frame(2), {{"Bad Name", "x"}}), std::invalid_argument);
  EXPECT_THROW(w.Append(Frame(2), {{"Field", "two\nlines"}}), std::invalid_argument);
  EXPECT_EQ(w.frames(), 2u);
  w.Append(Frame(2));  // a refused frame does not stop the recording
  const PlusSequence s = ReadPlusSequence(dir.path() / "v.mhd");
  ASSERT_EQ(s.frames.size(), 3u);
  for (int f = 0; f < 3; ++f) ExpectFrame(s, static_cast<std::size_t>(f), f);
  // A directory that does not exist: an I/O error naming the file.
  SequenceWriter nowhere(dir.path() / "missing" / "v.mhd");
  try {
    nowhere.Append(Frame(0));
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    ExpectContains(e.what(), "missing/v.raw");
  }
}

// A writer process appends frames as fast as it can and reports each Append that returned
// on a pipe; it is killed with SIGKILL at a random instant. Every reported frame must be
// in the recording, whole, and at most one more (the one in flight, when the kill came
// after its header was replaced).
TEST(SequenceWriter, AWriterKilledAtAnyInstantLosesAtMostTheFrameInFlight) {
  const testing::TempDir dir("seqw_kill", true);
  std::mt19937 rng(7);
  for (int trial = 0; trial < 6; ++trial) {
    const fs::path header = dir.path() / ("t" + std::to_string(trial) + ".mhd");
    int pipe_fds[2];
    ASSERT_EQ(::pipe(pipe_fds), 0);
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      ::close(pipe_fds[0]);
      SequenceWriter w(header);
      for (int i = 0;; ++i) {
        w.Append(Frame(i));
        const char byte = 1;
        if (::write(pipe_fds[1], &byte, 1) != 1) ::_exit(2);
      }
    }
    ::close(pipe_fds[1]);
    // Wait for a few frames, then kill after a random extra moment (mid-Append or not).
    const int wait_frames = 3 + trial;
    int reported = 0;
    char buf[256];
    while (reported < wait_frames) {
      const ssize_t n = ::read(pipe_fds[0], buf, 1);
      ASSERT_EQ(n, 1);
      ++reported;
    }
    ::usleep(std::uniform_int_distribution<useconds_t>(0, 3000)(rng));
    ASSERT_EQ(::kill(child, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status));
    for (ssize_t n; (n = ::read(pipe_fds[0], buf, sizeof buf)) > 0;)
      reported += static_cast<int>(n);
    ::close(pipe_fds[0]);

    const PlusSequence s = ReadPlusSequence(header);
    EXPECT_GE(s.frames.size(), static_cast<std::size_t>(reported)) << "trial " << trial;
    EXPECT_LE(s.frames.size(), static_cast<std::size_t>(reported) + 1) << "trial " << trial;
    for (std::size_t f = 0; f < s.frames.size(); ++f) ExpectFrame(s, f, static_cast<int>(f));
  }
}

}  // namespace
}  // namespace echoservo::imaging
