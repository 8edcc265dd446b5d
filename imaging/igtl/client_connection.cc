#include "imaging/igtl/client_connection.h"

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>

#include "imaging/igtl/ingest.h"
#include "imaging/igtl/tcp.h"

namespace echoservo::imaging::openigtlink {
namespace {

constexpr int kClientPollMs = 50;  // how often a read looks at the stop flag

}  // namespace

ReadStatus ReadPolled(int fd, std::uint8_t* p, std::size_t n, bool started,
                      const std::atomic<bool>& stop, int stall_timeout_ms) {
  using Clock = std::chrono::steady_clock;
  std::size_t total = 0;
  auto last_progress = Clock::now();
  while (total < n) {
    if (stop) return ReadStatus::kStopped;
    std::size_t got = 0;
    const tcp::IoResult r = tcp::ReadExact(fd, p + total, n - total, kClientPollMs, got);
    total += got;
    if (got > 0) last_progress = Clock::now();
    if (r == tcp::IoResult::kOk) break;
    const bool mid = started || total > 0;
    if (r == tcp::IoResult::kTimeout) {
      const double idle_ms =
          std::chrono::duration<double, std::milli>(Clock::now() - last_progress).count();
      if (mid && idle_ms > stall_timeout_ms) return ReadStatus::kStalled;
      continue;
    }
    if (r == tcp::IoResult::kClosed) return mid ? ReadStatus::kTruncated : ReadStatus::kClosedClean;
    return ReadStatus::kError;
  }
  return ReadStatus::kOk;
}

SessionReader::SessionReader(int fd, const std::atomic<bool>& stop, int stall_timeout_ms,
                             std::function<void(std::size_t n)> count_bytes,
                             std::function<void(const std::string& reason)> reject)
    : fd_(fd),
      stop_(stop),
      stall_timeout_ms_(stall_timeout_ms),
      count_bytes_(std::move(count_bytes)),
      reject_(std::move(reject)) {}

bool SessionReader::Read(std::uint8_t* p, std::size_t n, bool started) {
  const ReadStatus status = ReadPolled(fd_, p, n, started, stop_, stall_timeout_ms_);
  const char* rejection = nullptr;
  switch (status) {
    case ReadStatus::kOk:
      if (count_bytes_) count_bytes_(n);
      return true;
    case ReadStatus::kClosedClean:
      why_ = "closed by the server";
      break;
    case ReadStatus::kTruncated:
      rejection = "truncated_message";
      why_ = "closed by the server in the middle of a message";
      break;
    case ReadStatus::kStalled:
      rejection = "stalled";
      why_ = "no data for " + std::to_string(stall_timeout_ms_) + " ms in the middle of a message";
      break;
    case ReadStatus::kError:
      rejection = "socket_error";
      why_ = "socket error";
      break;
    case ReadStatus::kStopped:
      break;
  }
  if (rejection && reject_) reject_(rejection);
  return false;
}

void WaitUnlessStopped(std::mutex& mutex, std::condition_variable& cv,
                       const std::atomic<bool>& stop, double s) {
  std::unique_lock lock(mutex);
  cv.wait_for(lock, std::chrono::duration<double>(s), [&stop] { return stop.load(); });
}

void RunReconnectLoop(const ReconnectOptions& options, const std::atomic<bool>& stop,
                      const ReconnectHooks& hooks) {
  double backoff = options.reconnect_initial_s;
  int failures = 0;
  auto report = [&hooks](ConnectionEvent e) {
    if (!hooks.on_event) return;
    if (hooks.frames) e.frames = hooks.frames();
    hooks.on_event(e);
  };
  auto back_off = [&] {
    hooks.wait(backoff);
    backoff = std::min(2 * backoff, options.reconnect_max_s);
  };
  while (!stop) {
    std::string error;
    int error_number = 0;
    tcp::Fd fd =
        tcp::Connect(options.host, options.port, options.connect_timeout_ms, error, error_number);
    if (!fd.valid()) {
      if (stop) break;
      ++failures;
      if (hooks.connect_failed) hooks.connect_failed(error);
      const bool give_up =
          options.max_connect_failures >= 0 && failures > options.max_connect_failures;
      report({ConnectionEvent::Kind::kConnectFailed, failures, error, error_number,
              give_up ? 0.0 : backoff, 0});
      if (give_up) {
        report({ConnectionEvent::Kind::kGaveUp, failures, error, error_number, 0.0, 0});
        break;
      }
      back_off();
      continue;
    }
    report({ConnectionEvent::Kind::kConnected, failures + 1, "", 0, 0.0, 0});
    failures = 0;
    if (hooks.connected) hooks.connected();
    const std::int64_t progress_before = hooks.progress ? hooks.progress() : 0;
    const std::string why = hooks.session(fd.get());
    fd.reset();
    if (stop) break;
    if (hooks.progress && hooks.progress() > progress_before) backoff = options.reconnect_initial_s;
    if (hooks.disconnected) hooks.disconnected(why);
    report({ConnectionEvent::Kind::kDisconnected, 0, why, 0, backoff, 0});
    back_off();
  }
}

}  // namespace echoservo::imaging::openigtlink
