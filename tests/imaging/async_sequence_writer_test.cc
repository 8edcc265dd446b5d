// The volume recorder off the caller's thread (imaging/io/async_sequence_writer.h): what it
// records is a sequence `track --replay` reads back exactly and in order; a slow sink makes
// it drop (and count) the volumes that find the queue full, without ever making the caller
// wait; a failing sink stops the recording and keeps the error. No timing is asserted: the
// slow sink is held on a latch the test releases.
#include "imaging/io/async_sequence_writer.h"

#include <gtest/gtest.h>

#include <condition_variable>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>
#include <vector>

#include "imaging/io/recording.h"
#include "tests/imaging/sequence_test_frames.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::imaging {
namespace {

namespace fs = std::filesystem;
using test_frames::ExpectFrame;
using test_frames::Frame;

TEST(AsyncSequenceWriter, RecordsAReplayableSequenceInOrder) {
  const testing::TempDir dir("async_seqw", true);
  const fs::path header = dir.path() / "volumes.igs.mhd";
  {
    AsyncSequenceWriter w(header, 4);
    for (int i = 0; i < 6; ++i) {
      // Never more than one volume waits here: the writer catches up before the next.
      while (w.stats().written < static_cast<std::uint64_t>(i)) std::this_thread::yield();
      ASSERT_TRUE(w.Submit(Frame(i)));
    }
    w.Close();
    const AsyncRecorderStats s = w.stats();
    EXPECT_EQ(s.submitted, 6u);
    EXPECT_EQ(s.written, 6u);
    EXPECT_EQ(s.dropped, 0u);
    EXPECT_TRUE(s.error.empty()) << s.error;
    EXPECT_FALSE(w.Submit(Frame(6)));  // closed: dropped, counted
    EXPECT_EQ(w.stats().dropped, 1u);
  }
  // As `track --replay` opens it.
  auto source = OpenRecording(header);
  int n = 0;
  while (auto f = source->Next()) {
    ExpectFrame(f->volume, static_cast<std::size_t>(n), n);
    ++n;
  }
  EXPECT_EQ(n, 6);
}

// A sink held on a latch: the first volume enters it and stays until Release().
struct LatchedSink {
  std::mutex m;
  std::condition_variable cv;
  bool entered = false, released = false;
  std::vector<double> timestamps;

  void operator()(const Volume& v) {
    std::unique_lock lock(m);
    entered = true;
    cv.notify_all();
    cv.wait(lock, [this] { return released; });
    timestamps.push_back(v.timestamp_s());
  }
  void WaitEntered() {
    std::unique_lock lock(m);
    cv.wait(lock, [this] { return entered; });
  }
  void Release() {
    std::lock_guard lock(m);
    released = true;
    cv.notify_all();
  }
};

TEST(AsyncSequenceWriter, ASlowSinkDropsWhatFindsTheQueueFullInsteadOfBlocking) {
  LatchedSink sink;
  AsyncSequenceWriter w([&sink](const Volume& v) { sink(v); }, 3);
  ASSERT_TRUE(w.Submit(Frame(0)));
  sink.WaitEntered();  // the writer holds volume 0 in the stalled sink
  // Three fit the queue; the next three are dropped at once. Were Submit to wait for the
  // sink, this thread would never get past it (the latch opens only below).
  for (int i = 1; i <= 3; ++i) EXPECT_TRUE(w.Submit(Frame(i))) << i;
  for (int i = 4; i <= 6; ++i) EXPECT_FALSE(w.Submit(Frame(i))) << i;
  AsyncRecorderStats s = w.stats();
  EXPECT_EQ(s.submitted, 7u);
  EXPECT_EQ(s.dropped, 3u);
  EXPECT_EQ(s.written, 0u);
  EXPECT_EQ(s.queue_high_water, 4u);  // three waiting and one in the sink
  sink.Release();
  w.Close();  // the queued volumes are written before Close returns
  s = w.stats();
  EXPECT_EQ(s.written, 4u);
  EXPECT_EQ(s.dropped, 3u);
  // In order, the dropped ones absent.
  const auto summary = nlohmann::json::parse(w.SummaryJson());
  EXPECT_EQ(summary["volumes_recorded"], 4);
  EXPECT_EQ(summary["volumes_record_dropped"], 3);
  EXPECT_EQ(summary["queue_volumes"], 3);
  EXPECT_TRUE(summary["error"].is_null());
  ASSERT_EQ(sink.timestamps.size(), 4u);
  for (int i = 0; i < 4; ++i)
    EXPECT_DOUBLE_EQ(sink.timestamps[static_cast<std::size_t>(i)], Frame(i).timestamp_s());
}

TEST(AsyncSequenceWriter, AFailingSinkStopsTheRecordingAndKeepsTheError) {
  int calls = 0;
  AsyncSequenceWriter w(
      [&calls](const Volume&) {
        if (++calls == 2) throw std::runtime_error("disk full");
      },
      8);
  EXPECT_TRUE(w.Submit(Frame(0)));
  while (w.stats().written < 1) std::this_thread::yield();
  EXPECT_TRUE(w.Submit(Frame(1)));
  while (w.stats().error.empty()) std::this_thread::yield();
  EXPECT_FALSE(w.Submit(Frame(2)));  // the recording has stopped
  w.Close();
  const AsyncRecorderStats s = w.stats();
  EXPECT_EQ(s.written, 1u);
  EXPECT_EQ(s.dropped, 2u);
  EXPECT_EQ(s.error, "disk full");
  EXPECT_EQ(nlohmann::json::parse(w.SummaryJson())["error"], "disk full");
  EXPECT_EQ(calls, 2);
}

TEST(AsyncSequenceWriter, BadOptionsAreClearErrors) {
  const testing::TempDir dir("async_seqw_bad", true);
  EXPECT_THROW(AsyncSequenceWriter(dir.path() / "volumes.raw", 4), std::invalid_argument);
  EXPECT_THROW(AsyncSequenceWriter(dir.path() / "volumes.igs.mhd", 0), std::invalid_argument);
  EXPECT_THROW(AsyncSequenceWriter(AsyncSequenceWriter::Sink{}, 4), std::invalid_argument);
}

}  // namespace
}  // namespace echoservo::imaging
