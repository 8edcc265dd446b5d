// The one tracker runtime: a source (live/tracker_source.h: the simulated scanner, an
// OpenIGTLink scanner stream, a recording replayed) → TrackerNode (live/tracker_node.h:
// detector → predictor competition → estimate) → sinks: the DDS publisher and the RUN
// writer (the node's), the volume recorder (on its own thread, off the estimate's path), and
// `on_tracked` for the rest (the OpenIGTLink detection server, the demo's counters, a
// replay's scoring). `track`, `demo` and `tune trial` run it; nothing else drives TrackerNode.
//
// Clocks: the source's (node clock, s); link stamps = node time + link_offset_s of the node
// options. A volume the node cannot process is counted, logged through `log` and skipped; the
// run goes on. Errors: the constructor throws std::invalid_argument for bad options (the
// node's) and std::runtime_error when the recording cannot be created.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "formats/run_record.h"
#include "imaging/io/async_sequence_writer.h"
#include "live/tracker_node.h"
#include "live/tracker_source.h"

namespace echoservo::live {

struct TrackerRuntimeOptions {
  TrackerNodeOptions node;
  link::TargetPublisher* publisher = nullptr;  // may be null: nothing published
  formats::RunWriter* writer = nullptr;        // may be null: no RUN directory
  // Non-empty: the volumes as the tracker received them, to this PLUS sequence header
  // (RUN/volumes.igs.mhd), through a queue of record_queue_volumes (a full queue drops and
  // counts; 4.9 MB a volume).
  std::filesystem::path record_to;
  std::size_t record_queue_volumes = 16;  // ≥ 1
  // Each processed volume: the node's result, the source's volume (its stamp, arrival,
  // truth), and the node's processing time (ms). Called on the runtime's thread right after
  // the node, before the volume goes to the recorder: it must not block.
  std::function<void(const TrackedVolume&, const SourceVolume&, double process_ms)> on_tracked;
  std::function<void(const std::string&)> log;  // lines such as "volume skipped: …"
  std::function<bool()> stop;                   // checked between volumes; may be null
  double poll_s = 0.05;                         // the wait for a volume before checking stop
};

struct TrackerRunResult {
  TrackerStats stats;
  SourceCounts source;
  // What became of the volumes: acquired, missed by the scanner, shed (stale, superseded by a
  // newer one), processed, not found; with a RUN writer also its tracker.json.
  formats::TrackerVolumeCounts volumes;
  imaging::AsyncRecorderStats recorder;  // record_to only
  std::string recorder_summary_json;     // record_to only: RUN/volumes.json
};

class TrackerRuntime {
 public:
  explicit TrackerRuntime(TrackerRuntimeOptions options);
  ~TrackerRuntime();
  TrackerRuntime(const TrackerRuntime&) = delete;
  TrackerRuntime& operator=(const TrackerRuntime&) = delete;

  // Processes the source's volumes until it is finished or `stop` says so, on the calling
  // thread; then closes the recording (what is queued is written and synced) and writes its
  // summary next to it (volumes.json). One run per runtime.
  TrackerRunResult Run(TrackerSource& source);

  const TrackerNode& node() const { return node_; }

 private:
  TrackerRuntimeOptions o_;
  TrackerNode node_;
  std::unique_ptr<imaging::AsyncSequenceWriter> recorder_;
};

}  // namespace echoservo::live
