// Live EM tracking in: an OpenIGTLink client of a PLUS server (PlusServer's OpenIGTLink
// server) that receives one tool's poses from TRANSFORM messages (device name = the tool,
// e.g. CatheterTipToTracker) and TDATA messages (element names = the tools), validates them
// (tracking_messages.h), and hands each accepted sample to a callback.
//
// Units and frames: positions in mm in the tracker's frame (the transform's translation);
// times in s on the PLUS server's clock (the message header's timestamp, s since the Unix
// epoch). Samples reach the callback in strictly increasing time: a duplicate timestamp
// (PLUS resends the last pose when the tracker has nothing new) or an older one is skipped
// and counted, never handed on twice.
// Drop-outs: PLUS marks a tool it cannot see with status metadata ("TransformStatus",
// "<name>Status" ≠ "OK") on header-version-2 links, and by an identity matrix on version-1
// links (its SendValidTransformsOnly="FALSE"; with the default TRUE it sends nothing, a gap):
// such a sample is handed on with valid = false and counted by reason.
// Errors: a bad message whose framing holds is rejected and counted by reason (and device
// name); a garbage or oversize header drops the connection; the client reconnects with
// exponential back-off and keeps running without data. Start throws std::invalid_argument
// for bad options.
// Details: docs/report.md#live-em-tracking-from-plus
#pragma once

#include <Eigen/Geometry>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include "imaging/igtl/image_message.h"
#include "imaging/igtl/ingest.h"
#include "imaging/igtl/tracking_messages.h"

namespace echoservo::imaging::openigtlink {

struct EmStreamSample {
  std::string tool;
  double t_s = 0.0;  // the PLUS server's clock (message timestamp)
  Eigen::Isometry3d tool_to_tracker = Eigen::Isometry3d::Identity();  // mm
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();              // its translation
  bool valid = true;
  std::string dropout_reason;  // when !valid: "identity", or PLUS's status ("MISSING", …)
};

struct EmStreamOptions {
  std::string host = "127.0.0.1";
  int port = 0;
  // The tool to record (TRANSFORM device name or TDATA element name, ≤ 20 bytes). Empty:
  // the only tool streaming; once a second tool appears, nothing more is accepted and
  // stats().tool_error lists the tools seen.
  std::string tool;
  TrackingDecodeLimits limits;
  // Bodies of TRANSFORM, TDATA and STATUS above this are rejected (body_too_large) and
  // skipped unread; other types (IMAGE, …) are skipped up to DecodeLimits' 64 MiB.
  std::size_t max_tracking_body_bytes = 64 << 10;
  double reconnect_initial_s = 0.02;
  double reconnect_max_s = 1.0;
  int connect_timeout_ms = 1000;
  int stall_timeout_ms = 3000;  // mid-message silence before the connection is dropped
  // Called on the receive thread, in increasing t_s; keep it short. Required.
  std::function<void(const EmStreamSample&)> on_sample;
  // Connection events (ingest.h's ConnectionEvent; `frames` counts samples); may be empty.
  std::function<void(const ConnectionEvent&)> on_event;
};

struct EmStreamStats {
  std::int64_t connections = 0;  // successful connects
  std::int64_t connect_failures = 0;
  std::int64_t disconnects = 0;  // established connections that ended (not by Stop)
  std::int64_t reconnects = 0;   // connections after the first
  std::int64_t messages = 0;     // whole messages read
  std::int64_t samples = 0;      // handed to on_sample (valid or not)
  std::int64_t valid_samples = 0;
  std::int64_t duplicates_skipped = 0;  // the tool's timestamp equal to the last one's
  std::int64_t older_skipped = 0;       // the tool's timestamp before the last one's
  std::map<std::string, std::int64_t> dropouts_by_reason;
  std::int64_t rejected = 0;  // sum of rejected_by_reason
  std::map<std::string, std::int64_t> rejected_by_reason;
  // "reason device" → count, e.g. "non_orthonormal CatheterTipToTracker".
  std::map<std::string, std::int64_t> rejected_by_device;
  std::map<std::string, std::int64_t> skipped_by_type;  // valid messages of other types
  std::map<std::string, std::int64_t> tools_seen;       // tool → poses received (any tool)
  std::map<std::string, std::int64_t> status_by_code;   // STATUS messages by code
  std::string tool;        // the tool recorded (options.tool, or the only one streaming)
  std::string tool_error;  // several tools without options.tool: which
  std::string last_error;  // the newest connect failure or disconnection reason
  double first_t_s = 0.0, last_t_s = 0.0;  // of the samples handed on
  std::int64_t bytes = 0;
};

class EmStreamClient {
 public:
  explicit EmStreamClient(EmStreamOptions options);
  ~EmStreamClient();
  EmStreamClient(const EmStreamClient&) = delete;
  EmStreamClient& operator=(const EmStreamClient&) = delete;

  void Start();  // starts the receive thread (throws std::invalid_argument on bad options)
  void Stop();   // closes the connection and joins the thread. Idempotent.
  EmStreamStats stats() const;

 private:
  void Run();
  std::string Session(int fd);  // returns why the session ended
  void Reject(const std::string& reason, const std::string& device);
  void Handle(const MessageHeader& header, std::span<const std::uint8_t> body);
  void Offer(const std::string& tool, double t_s, const TrackedTransform& pose,
             const std::string& status);

  EmStreamOptions options_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  EmStreamStats stats_;
  bool any_sample_ = false;
  std::thread thread_;
};

}  // namespace echoservo::imaging::openigtlink
