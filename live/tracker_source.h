// Where the tracker runtime's volumes come from (live/tracker_runtime.h): the embedded
// simulated scanner, a recording replayed offline, or an OpenIGTLink scanner stream
// (live/igtl_source.h). Each gives a volume with its stamp and arrival on the node clock, the
// node clock itself, and its counts; the runtime does the rest the same way for all three.
//
// Clocks (s): the simulated scanner's pipeline clock (since the run's start; link time =
// pipeline time + link_offset_s); a replay's own timestamps (offline: arrival = stamp = now);
// the scanner stream's system clock (since the Unix epoch). unix_offset_s converts a stamp
// to the system clock (viewers, EM logs). Errors: std::invalid_argument naming the recording
// (a file that cannot be read, a bad frame, a bad truth field).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "imaging/volume.h"
#include "imaging/volume_source.h"
#include "live/delayed_scanner.h"
#include "live/pipeline_clock.h"

namespace echoservo::live {

struct SourceVolume {
  imaging::Volume volume;
  double stamp_s = 0.0;    // the scanner's stamp (the acquisition, unless it stamps late)
  double arrived_s = 0.0;  // node clock
  std::size_t index = 0;   // the source's count of volumes delivered so far, from 0
  std::optional<imaging::FrameGroundTruth> truth;  // a simulated recording's, when known
};

struct SourceCounts {
  std::uint64_t acquired = 0;  // volumes the source acquired or read
  std::uint64_t missed = 0;    // acquisition slots lost (a late renderer)
  std::uint64_t dropped = 0;   // delivered late and superseded, or dropped by a full queue
  std::uint64_t skipped = 0;   // a replay's frames whose timestamp did not increase
};

class TrackerSource {
 public:
  virtual ~TrackerSource() = default;
  // The next volume, waiting up to timeout_s; nullopt when none came (then see finished()).
  virtual std::optional<SourceVolume> Next(double timeout_s) = 0;
  virtual bool finished() const = 0;  // nothing more will come
  virtual double Now() const = 0;     // node clock
  // System clock (s since the Unix epoch) = node clock + unix_offset_s.
  virtual double unix_offset_s() const { return 0.0; }
  virtual void Stop() {}  // from any thread: Next returns soon, finished() turns true
  virtual SourceCounts counts() const = 0;
};

// The embedded simulated scanner (live/delayed_scanner.h) on a pipeline clock: it acquires
// from `scene` at rate_hz and delivers each volume after a random imaging delay.
class SimScannerSource : public TrackerSource {
 public:
  // `scene` and `clock` must outlive the source. Acquisition starts at once.
  SimScannerSource(SimScene& scene, const PipelineClock& clock, DelayedScannerOptions options);
  std::optional<SourceVolume> Next(double timeout_s) override;
  bool finished() const override;
  double Now() const override { return clock_.Now(); }
  double unix_offset_s() const override { return clock_.link_offset_s(); }
  void Stop() override { scanner_.Stop(); }
  SourceCounts counts() const override;

 private:
  const PipelineClock& clock_;
  DelayedScanner scanner_;
  std::size_t next_index_ = 0;
};

// A recording (PLUS sequence, volume file or folder: imaging/io/recording.h) replayed in
// order on its own timestamps, as fast as the tracker goes. A frame whose timestamp does not
// increase is skipped, counted and reported through `on_skip` (the tracker needs increasing
// acquisition times).
class ReplaySource : public TrackerSource {
 public:
  // Throws std::invalid_argument naming `path` when it cannot be opened.
  ReplaySource(const std::filesystem::path& path,
               std::function<void(const std::string&)> on_skip = {});
  std::optional<SourceVolume> Next(double timeout_s) override;
  bool finished() const override { return finished_; }
  double Now() const override { return now_s_; }
  void Stop() override { finished_ = true; }
  SourceCounts counts() const override { return counts_; }

 private:
  std::filesystem::path path_;
  std::unique_ptr<imaging::VolumeSource> source_;
  std::function<void(const std::string&)> on_skip_;
  double last_s_ = -1e300, now_s_ = 0.0;
  std::size_t frame_ = 0, next_index_ = 0;
  bool finished_ = false;
  SourceCounts counts_;
};

}  // namespace echoservo::live
