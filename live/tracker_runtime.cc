#include "live/tracker_runtime.h"

#include <chrono>
#include <stdexcept>
#include <utility>

#include "formats/durable_file.h"

namespace echoservo::live {

TrackerRuntime::TrackerRuntime(TrackerRuntimeOptions options)
    : o_(std::move(options)), node_(o_.node, o_.publisher, o_.writer) {
  if (o_.record_queue_volumes < 1)
    throw std::invalid_argument("TrackerRuntimeOptions::record_queue_volumes must be ≥ 1");
  if (!o_.record_to.empty())
    recorder_ =
        std::make_unique<imaging::AsyncSequenceWriter>(o_.record_to, o_.record_queue_volumes);
}

TrackerRuntime::~TrackerRuntime() = default;

TrackerRunResult TrackerRuntime::Run(TrackerSource& source) {
  using Clock = std::chrono::steady_clock;
  const std::function<double()> now = [&source] { return source.Now(); };
  while (!(o_.stop && o_.stop())) {
    std::optional<SourceVolume> v = source.Next(o_.poll_s);
    if (!v) {
      if (source.finished()) break;
      continue;
    }
    const auto t0 = Clock::now();
    const TrackedVolume r = node_.Process(v->volume, v->stamp_s, v->arrived_s, now);
    const double process_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    if (!r.error.empty() && o_.log) o_.log("volume skipped: " + r.error);
    if (o_.on_tracked) o_.on_tracked(r, *v, process_ms);
    if (recorder_) recorder_->Submit(std::move(v->volume));
  }
  source.Stop();
  TrackerRunResult result;
  result.stats = node_.stats();
  result.source = source.counts();
  result.volumes.acquired = result.source.acquired;
  result.volumes.missed = result.source.missed;
  result.volumes.shed = result.source.dropped;
  result.volumes.skipped = result.source.skipped;
  result.volumes.processed = result.stats.volumes;
  result.volumes.not_found = result.stats.not_found;
  if (o_.writer)
    formats::ReplaceFileContents(o_.writer->dir() / "tracker.json",
                                 formats::TrackerCountsJson(result.volumes) + "\n");
  if (o_.log && result.volumes.shed > 0)
    o_.log("tracker: " + std::to_string(result.volumes.shed) + " of " +
           std::to_string(result.volumes.acquired) +
           " volumes shed (stale: a newer one had arrived before the tracker was free)");
  if (recorder_) {  // what is queued is written, then synced
    recorder_->Close();
    result.recorder = recorder_->stats();
    result.recorder_summary_json = recorder_->SummaryJson();
    formats::ReplaceFileContents(o_.record_to.parent_path() / "volumes.json",
                                 result.recorder_summary_json);
    if (o_.log) {
      if (!result.recorder.error.empty())
        o_.log("volume recording stopped: " + result.recorder.error);
      if (result.recorder.dropped > 0)
        o_.log("volume recording: " + std::to_string(result.recorder.dropped) + " of " +
               std::to_string(result.recorder.submitted) + " volumes dropped (recorder queue of " +
               std::to_string(recorder_->queue_capacity()) + " full)");
    }
  }
  return result;
}

}  // namespace echoservo::live
