// The simulated scanner as the tracker sees it: volumes acquired on the scanner's own
// schedule (k / rate_hz on the pipeline clock; slots missed while rendering are lost and
// counted), each delivered after an imaging delay drawn uniformly from
// [delay_min_s, delay_max_s] (in order, as a scanner's network stream delivers them).
// A thread renders (on one TBB thread, leaving the other cores to the tracker and servo);
// the consumer takes the newest delivered volume, older ones it fell behind on are dropped
// and counted. Times in s on the pipeline clock.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>

#include "imaging/volume.h"
#include "live/pipeline_clock.h"

namespace echoservo::live {

class SimScene;

struct DelayedScannerOptions {
  double rate_hz = 25.0;
  double delay_min_s = 0.05;
  double delay_max_s = 0.10;
  double duration_s = 20.0;  // no acquisition after this time
  std::uint64_t seed = 1;
};

struct Delivery {
  imaging::Volume volume;
  double acquired_s = 0.0;
  double deliver_s = 0.0;
};

class DelayedScanner {
 public:
  // Starts acquiring at once. `scene` and `clock` must outlive the scanner.
  DelayedScanner(SimScene& scene, const PipelineClock& clock, DelayedScannerOptions options);
  ~DelayedScanner();  // stops and joins
  DelayedScanner(const DelayedScanner&) = delete;
  DelayedScanner& operator=(const DelayedScanner&) = delete;

  // Waits up to timeout_s for a volume, then sleeps until its delivery time; nullopt on
  // timeout or once stopped and drained.
  std::optional<Delivery> Next(double timeout_s);
  void Stop();
  bool finished() const { return finished_; }  // acquisition ended (duration reached)

  std::uint64_t acquired() const { return acquired_; }
  std::uint64_t missed() const { return missed_; }  // acquisition slots lost
  // Delivered but superseded by a newer one, or acquired and still queued (acquired =
  // delivered + dropped at any time).
  std::uint64_t dropped() const;

 private:
  void Run();

  SimScene& scene_;
  const PipelineClock& clock_;
  DelayedScannerOptions o_;
  std::atomic<bool> stop_{false}, finished_{false};
  std::atomic<std::uint64_t> acquired_{0}, missed_{0}, dropped_{0};
  mutable std::mutex m_;
  std::condition_variable cv_;
  std::deque<Delivery> queue_;
  std::thread thread_;
};

}  // namespace echoservo::live
