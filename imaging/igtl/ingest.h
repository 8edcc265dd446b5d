// OpenIGTLink ingest client: connects to any OpenIGTLink server (HOST:PORT), validates every
// message (image_message.h), and offers the accepted IMAGE frames as an imaging::VolumeSource.
//
// Reconnects with exponential backoff; a bad message whose framing is trusted is skipped, a
// garbage or oversize header drops the connection. Accepted frames go to a bounded queue
// that drops (and counts) the oldest. Frames are stamped on arrival (wall clock, s since the
// Unix epoch); latency (ms, arrival − message timestamp) only on a shared clock; receive
// time (ms) per frame. Start throws std::invalid_argument on bad options; a receive thread
// runs until Stop.
// Details: docs/openigtlink.md#the-ingest-client-imagingigtlingesth
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "imaging/igtl/image_message.h"
#include "imaging/volume_source.h"

namespace echoservo::imaging::openigtlink {

// What the receive thread reports as the connection comes and goes (IngestOptions::on_event).
struct ConnectionEvent {
  enum class Kind {
    kConnectFailed,  // attempt `attempt` failed: `error` (errno `error_number`)
    kConnected,      // attempt `attempt` connected
    kDisconnected,   // the connection ended: `error` says why
    kGaveUp,         // max_connect_failures reached: no more attempts
  };
  Kind kind = Kind::kConnectFailed;
  int attempt = 0;          // connect attempts since the last connection, from 1
  std::string error;        // "connection refused (ECONNREFUSED)", "closed by the server", ...
  int error_number = 0;     // errno of a failed connect (0 when it has none)
  double retry_in_s = 0;    // kConnectFailed, kDisconnected: wait before the next attempt
  std::int64_t frames = 0;  // accepted IMAGE frames so far
};

struct IngestOptions {
  std::string host = "127.0.0.1";
  int port = 0;
  DecodeLimits limits;
  std::size_t queue_capacity = 4;  // ≥ 1
  double reconnect_initial_s = 0.02;
  double reconnect_max_s = 1.0;
  int max_connect_failures = -1;  // consecutive failed connects before giving up; < 0: never
  int connect_timeout_ms = 1000;
  int stall_timeout_ms = 3000;  // mid-message silence before the connection is dropped
  enum class Clock { kAuto, kShared, kSeparate };
  Clock clock = Clock::kAuto;
  std::size_t max_samples = 1 << 20;  // latency samples kept
  // Called on the receive thread for each connection event (keep it short); may be empty.
  std::function<void(const ConnectionEvent&)> on_event;
};

struct LatencySummary {
  std::int64_t count = 0;
  double p50_ms = 0, p99_ms = 0, max_ms = 0, mean_ms = 0;
};

struct IngestStats {
  std::int64_t frames = 0;    // accepted IMAGE frames
  std::int64_t rejected = 0;  // sum of rejected_by_reason
  std::map<std::string, std::int64_t> rejected_by_reason;
  std::int64_t skipped = 0;  // valid non-IMAGE messages
  std::map<std::string, std::int64_t> skipped_by_type;
  std::int64_t dropped = 0;      // accepted, then dropped from the full queue
  std::int64_t delivered = 0;    // handed to the consumer
  std::int64_t connections = 0;  // successful connects
  std::int64_t connect_failures = 0;
  std::string last_connect_error;  // the newest failed connect's error (ConnectionEvent::error)
  std::int64_t bytes = 0;
  LatencySummary latency;  // arrival − message timestamp (shared clock only)
  LatencySummary receive;  // per-frame receive time
  double elapsed_s = 0;    // since Start()
};

struct IngestedFrame {
  SourceFrame frame;  // volume timestamp = message timestamp
  std::string device_name;
  double arrival_s = 0;  // wall clock, s since the Unix epoch
  double receive_ms = 0;
  std::optional<double> latency_ms;
};

class IngestClient : public VolumeSource {
 public:
  explicit IngestClient(IngestOptions options);
  ~IngestClient() override;
  IngestClient(const IngestClient&) = delete;
  IngestClient& operator=(const IngestClient&) = delete;

  void Start();  // starts the receive thread (throws std::invalid_argument on bad options)
  void Stop();   // closes the connection; Next() then returns nullopt. Idempotent.

  // The oldest queued frame, waiting up to timeout_s; nullopt on timeout or after Stop()
  // / giving up connecting.
  std::optional<IngestedFrame> NextFrame(double timeout_s);
  // VolumeSource: blocks until a frame arrives or the stream ends.
  std::optional<SourceFrame> Next() override;
  // Arrival rate over the last frames (vol/s), 0 before two frames.
  double nominal_rate_hz() const override;

  IngestStats stats() const;
  bool ended() const { return ended_; }

 private:
  void Run();
  std::string Session(int fd);  // returns why the session ended
  void Reject(const std::string& reason);
  void Accept(IngestedFrame frame);

  IngestOptions options_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> ended_{false};
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<IngestedFrame> queue_;
  IngestStats stats_;
  std::vector<double> latency_ms_, receive_ms_;
  std::deque<double> recent_arrivals_;
  double start_s_ = 0;
  std::thread thread_;
};

// p50/p99/max/mean of samples (ms).
LatencySummary Summarize(std::vector<double> samples);

}  // namespace echoservo::imaging::openigtlink
