// Connection plumbing shared by the OpenIGTLink clients (ingest.h's IngestClient and
// em_stream.h's EmStreamClient; internal to imaging/igtl): a polled exact read that honours
// a stop flag and tells a clean close from a message cut short or stalled, and the
// reconnect loop (connect, run a session, back off exponentially, optionally give up) that
// reports ConnectionEvents. The per-client bookkeeping (stats under the client's own mutex)
// stays with the client, through hooks called on the receive thread.
// Units: timeouts in ms, back-off in s (doubled after each failed connect or ended session,
// capped at reconnect_max_s, back to reconnect_initial_s after a session that made progress).
// Errors: nothing here throws (a hook may); read failures come back as a ReadStatus (from
// SessionReader as false, with why() and a rejection reason), connect failures and
// disconnections as ConnectionEvents (error text as tcp.h's Connect writes it).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>

namespace echoservo::imaging::openigtlink {

struct ConnectionEvent;  // ingest.h

enum class ReadStatus { kOk, kClosedClean, kTruncated, kStalled, kStopped, kError };

// Reads exactly n bytes from fd, polling so that `stop` is honoured. `started`: a message is
// already under way, so a close is a truncation (kTruncated, otherwise kClosedClean before
// its first byte) and stall_timeout_ms without a byte a stall (kStalled; before the first
// byte of a message it waits indefinitely). kOk: all n bytes are in p.
ReadStatus ReadPolled(int fd, std::uint8_t* p, std::size_t n, bool started,
                      const std::atomic<bool>& stop, int stall_timeout_ms);

// The reads of one session on fd, through ReadPolled: counts the bytes of each whole read
// (count_bytes(n)), and on a failed read records why the session must end and hands the
// rejection reason ("truncated_message", "stalled", "socket_error"; none for a clean close or
// a stop) to reject. Both hooks run on the caller's thread and may be empty.
class SessionReader {
 public:
  SessionReader(int fd, const std::atomic<bool>& stop, int stall_timeout_ms,
                std::function<void(std::size_t n)> count_bytes,
                std::function<void(const std::string& reason)> reject);
  // Reads exactly n bytes into p (`started` as for ReadPolled); false when the session must
  // end, why() then says why.
  bool Read(std::uint8_t* p, std::size_t n, bool started);
  // "closed by the server", "no data for 3000 ms in the middle of a message", ...;
  // "stopped" until a read fails (or when stopped).
  const std::string& why() const { return why_; }

 private:
  int fd_;
  const std::atomic<bool>& stop_;
  int stall_timeout_ms_;
  std::function<void(std::size_t)> count_bytes_;
  std::function<void(const std::string&)> reject_;
  std::string why_ = "stopped";
};

// Waits s seconds on cv (under mutex), returning early once `stop` is set.
void WaitUnlessStopped(std::mutex& mutex, std::condition_variable& cv,
                       const std::atomic<bool>& stop, double s);

struct ReconnectOptions {
  std::string host;
  int port = 0;
  int connect_timeout_ms = 1000;
  double reconnect_initial_s = 0.02;
  double reconnect_max_s = 1.0;
  int max_connect_failures = -1;  // consecutive failed connects before giving up; < 0: never
};

// All called on the receive thread; session and wait are required, the others may be empty.
struct ReconnectHooks {
  std::function<void(const std::string& error)> connect_failed;  // before its event
  std::function<void()> connected;                               // after its event
  std::function<std::string(int fd)> session;  // runs the connection; returns why it ended
  // A count that grows as messages get through: a session that raised it made progress.
  std::function<std::int64_t()> progress;
  std::function<void(const std::string& why)> disconnected;  // not after a stop; before its event
  std::function<std::int64_t()> frames;                      // ConnectionEvent::frames
  std::function<void(const ConnectionEvent& event)> on_event;
  std::function<void(double s)> wait;  // stop-aware back-off wait
};

// Connects, runs hooks.session on the connection, and reconnects with exponential back-off
// until `stop` is set or max_connect_failures consecutive failed connects are exceeded
// (then kGaveUp). Returns when the loop ends.
void RunReconnectLoop(const ReconnectOptions& options, const std::atomic<bool>& stop,
                      const ReconnectHooks& hooks);

}  // namespace echoservo::imaging::openigtlink
