#include "live/tracker_source.h"

#include <stdexcept>
#include <utility>

#include "imaging/io/recording.h"

namespace echoservo::live {

SimScannerSource::SimScannerSource(SimScene& scene, const PipelineClock& clock,
                                   DelayedScannerOptions options)
    : clock_(clock), scanner_(scene, clock, options) {}

std::optional<SourceVolume> SimScannerSource::Next(double timeout_s) {
  std::optional<Delivery> d = scanner_.Next(timeout_s);
  if (!d) return std::nullopt;
  const double arrived_s = clock_.Now();
  return SourceVolume{std::move(d->volume), d->acquired_s, arrived_s, next_index_++, std::nullopt};
}

bool SimScannerSource::finished() const { return scanner_.finished(); }

SourceCounts SimScannerSource::counts() const {
  SourceCounts c;
  c.acquired = scanner_.acquired();
  c.missed = scanner_.missed();
  c.dropped = scanner_.dropped();
  return c;
}

ReplaySource::ReplaySource(const std::filesystem::path& path,
                           std::function<void(const std::string&)> on_skip)
    : path_(path), source_(imaging::OpenRecording(path)), on_skip_(std::move(on_skip)) {}

std::optional<SourceVolume> ReplaySource::Next(double) {
  while (!finished_) {
    std::optional<imaging::SourceFrame> f;
    try {
      f = source_->Next();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("recording " + path_.string() + ": frame " +
                                  std::to_string(frame_) + ": " + e.what());
    }
    if (!f) {
      finished_ = true;
      break;
    }
    ++frame_;
    ++counts_.acquired;
    const double t = f->volume.timestamp_s();
    if (!(t > last_s_)) {
      ++counts_.skipped;
      if (on_skip_)
        on_skip_(path_.string() + " frame " + std::to_string(f->volume.frame_index()) +
                 ": timestamp " + std::to_string(t) + " s does not increase; skipped");
      continue;
    }
    last_s_ = now_s_ = t;
    return SourceVolume{std::move(f->volume), t, t, next_index_++, std::move(f->truth)};
  }
  return std::nullopt;
}

}  // namespace echoservo::live
