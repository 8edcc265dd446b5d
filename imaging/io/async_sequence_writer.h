// Volume recording off the caller's thread (`demo --save-volumes`, `track --save-volumes`):
// the caller hands a volume over (moved, no copy) to a bounded queue and goes on; one
// writer thread appends the queued volumes to an imaging::SequenceWriter (a crash-safe
// PLUS sequence that `track --replay` reads), in order.
//
// Never blocks the caller on the disk: a volume submitted while the queue holds
// `queue_capacity` volumes is dropped and counted (the recording then has a gap; its
// timestamps still increase). After a write error the recording stops (what was written
// stays readable), further volumes are counted as dropped and the error is kept for the
// summary. The writer thread keeps the default scheduling priority: at nice +5 and +10 it
// fell behind and dropped on a loaded 2-core host (a 4.9 MB volume into the page cache
// took ~24 ms of CPU there).
// Errors: the constructor throws std::invalid_argument for a header path not ending in
// .mhd (SequenceWriter's rule) or a zero queue capacity.
// Details: docs/live.md#recording-volumes-without-slowing-the-run
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "imaging/volume.h"

namespace echoservo::imaging {

class SequenceWriter;

struct AsyncRecorderStats {
  std::uint64_t submitted = 0;         // volumes handed to Submit
  std::uint64_t written = 0;           // appended to the recording
  std::uint64_t dropped = 0;           // not recorded: queue full, or after a write error
  std::uint64_t queue_high_water = 0;  // most volumes waiting at once
  std::string error;                   // the write error that stopped the recording, if any
};

class AsyncSequenceWriter {
 public:
  // What writes one volume on the writer thread (tests: a slow or failing sink); it may
  // throw to stop the recording.
  using Sink = std::function<void(const Volume&)>;

  // Records to `header_path` (imaging::SequenceWriter: <name>.mhd + <name>.raw).
  AsyncSequenceWriter(std::filesystem::path header_path, std::size_t queue_capacity);
  // Hands each volume to `sink` instead of a file.
  AsyncSequenceWriter(Sink sink, std::size_t queue_capacity);
  ~AsyncSequenceWriter();  // Close()
  AsyncSequenceWriter(const AsyncSequenceWriter&) = delete;
  AsyncSequenceWriter& operator=(const AsyncSequenceWriter&) = delete;

  // Queues `volume` for writing; false when it was dropped (queue full, recording stopped
  // or closed). Never waits for the disk.
  bool Submit(Volume volume);
  // Writes what is queued, syncs the data file (fdatasync) and stops the writer thread.
  // Idempotent; Submit afterwards drops.
  void Close();

  AsyncRecorderStats stats() const;
  std::size_t queue_capacity() const { return capacity_; }
  // The counts as JSON text, for a RUN directory's volumes.json: {"volumes_recorded",
  // "volumes_record_dropped", "volumes_submitted", "queue_volumes", "queue_high_water",
  // "error"}.
  std::string SummaryJson() const;

 private:
  void Run();

  std::unique_ptr<SequenceWriter> file_;  // null with a caller's sink
  Sink sink_;
  std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Volume> queue_;
  bool closing_ = false;
  bool writing_ = false;  // the writer thread holds a volume
  AsyncRecorderStats stats_;
  std::thread thread_;
};

}  // namespace echoservo::imaging
