#include "imaging/igtl/ingest.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "imaging/igtl/crc64.h"
#include "imaging/igtl/tcp.h"

namespace echoservo::imaging::openigtlink {
namespace {

using Steady = std::chrono::steady_clock;

double MsSince(Steady::time_point t) {
  return std::chrono::duration<double, std::milli>(Steady::now() - t).count();
}

enum class ReadStatus { kOk, kClosedClean, kTruncated, kStalled, kStopped, kError };

constexpr int kPollMs = 50;

}  // namespace

LatencySummary Summarize(std::vector<double> samples) {
  LatencySummary s;
  s.count = static_cast<std::int64_t>(samples.size());
  if (samples.empty()) return s;
  std::sort(samples.begin(), samples.end());
  auto pct = [&](double p) {
    const double pos = p * static_cast<double>(samples.size() - 1);
    const auto lo = static_cast<std::size_t>(std::floor(pos));
    const auto hi = std::min(lo + 1, samples.size() - 1);
    return samples[lo] + (pos - static_cast<double>(lo)) * (samples[hi] - samples[lo]);
  };
  s.p50_ms = pct(0.50);
  s.p99_ms = pct(0.99);
  s.max_ms = samples.back();
  double sum = 0;
  for (double v : samples) sum += v;
  s.mean_ms = sum / static_cast<double>(samples.size());
  return s;
}

IngestClient::IngestClient(IngestOptions options) : options_(std::move(options)) {}

IngestClient::~IngestClient() { Stop(); }

void IngestClient::Start() {
  if (options_.port < 1 || options_.port > 65535) {
    throw std::invalid_argument("ingest: port " + std::to_string(options_.port) +
                                " is not in 1..65535");
  }
  if (options_.queue_capacity < 1)
    throw std::invalid_argument("ingest: queue_capacity must be >= 1");
  if (!(options_.reconnect_initial_s > 0) ||
      options_.reconnect_max_s < options_.reconnect_initial_s) {
    throw std::invalid_argument("ingest: need 0 < reconnect_initial_s <= reconnect_max_s");
  }
  start_s_ = WallClockSeconds();
  thread_ = std::thread([this] { Run(); });
}

void IngestClient::Stop() {
  stop_ = true;
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  ended_ = true;
  cv_.notify_all();
}

std::optional<IngestedFrame> IngestClient::NextFrame(double timeout_s) {
  std::unique_lock lock(mutex_);
  cv_.wait_for(lock, std::chrono::duration<double>(std::max(0.0, timeout_s)),
               [this] { return !queue_.empty() || ended_.load() || stop_.load(); });
  if (queue_.empty()) return std::nullopt;
  IngestedFrame f = std::move(queue_.front());
  queue_.pop_front();
  ++stats_.delivered;
  return f;
}

std::optional<SourceFrame> IngestClient::Next() {
  while (true) {
    auto f = NextFrame(0.5);
    if (f) return std::move(f->frame);
    if (ended_ || stop_) return std::nullopt;
  }
}

double IngestClient::nominal_rate_hz() const {
  std::lock_guard lock(mutex_);
  if (recent_arrivals_.size() < 2) return 0.0;
  const double span = recent_arrivals_.back() - recent_arrivals_.front();
  return span > 0 ? static_cast<double>(recent_arrivals_.size() - 1) / span : 0.0;
}

IngestStats IngestClient::stats() const {
  std::lock_guard lock(mutex_);
  IngestStats s = stats_;
  s.latency = Summarize(latency_ms_);
  s.receive = Summarize(receive_ms_);
  s.elapsed_s = WallClockSeconds() - start_s_;
  return s;
}

void IngestClient::Reject(const std::string& reason) {
  std::lock_guard lock(mutex_);
  ++stats_.rejected;
  ++stats_.rejected_by_reason[reason];
}

void IngestClient::Accept(IngestedFrame frame) {
  {
    std::lock_guard lock(mutex_);
    frame.frame.volume.set_frame_index(stats_.frames);
    ++stats_.frames;
    if (frame.latency_ms && latency_ms_.size() < options_.max_samples) {
      latency_ms_.push_back(*frame.latency_ms);
    }
    if (receive_ms_.size() < options_.max_samples) receive_ms_.push_back(frame.receive_ms);
    recent_arrivals_.push_back(frame.arrival_s);
    if (recent_arrivals_.size() > 32) recent_arrivals_.pop_front();
    if (queue_.size() >= options_.queue_capacity) {
      queue_.pop_front();
      ++stats_.dropped;
    }
    queue_.push_back(std::move(frame));
  }
  cv_.notify_all();
}

void IngestClient::Run() {
  double backoff = options_.reconnect_initial_s;
  int failures = 0;
  auto wait = [this](double s) {
    std::unique_lock lock(mutex_);
    cv_.wait_for(lock, std::chrono::duration<double>(s), [this] { return stop_.load(); });
  };
  auto report = [this](ConnectionEvent e) {
    if (!options_.on_event) return;
    {
      std::lock_guard lock(mutex_);
      e.frames = stats_.frames;
    }
    options_.on_event(e);
  };
  while (!stop_) {
    std::string error;
    int error_number = 0;
    tcp::Fd fd = tcp::Connect(options_.host, options_.port, options_.connect_timeout_ms, error,
                              error_number);
    if (!fd.valid()) {
      if (stop_) break;
      ++failures;
      {
        std::lock_guard lock(mutex_);
        ++stats_.connect_failures;
        stats_.last_connect_error = error;
      }
      const bool give_up =
          options_.max_connect_failures >= 0 && failures > options_.max_connect_failures;
      ConnectionEvent e;
      e.kind = ConnectionEvent::Kind::kConnectFailed;
      e.attempt = failures;
      e.error = error;
      e.error_number = error_number;
      e.retry_in_s = give_up ? 0.0 : backoff;
      report(e);
      if (give_up) {
        report({ConnectionEvent::Kind::kGaveUp, failures, error, error_number, 0.0, 0});
        break;
      }
      wait(backoff);
      backoff = std::min(2 * backoff, options_.reconnect_max_s);
      continue;
    }
    report({ConnectionEvent::Kind::kConnected, failures + 1, "", 0, 0.0, 0});
    failures = 0;
    std::int64_t frames_before;
    {
      std::lock_guard lock(mutex_);
      ++stats_.connections;
      frames_before = stats_.frames + stats_.skipped;
    }
    const std::string why = Session(fd.get());
    fd.reset();
    {
      std::lock_guard lock(mutex_);
      if (stats_.frames + stats_.skipped > frames_before) backoff = options_.reconnect_initial_s;
    }
    if (stop_) break;
    report({ConnectionEvent::Kind::kDisconnected, 0, why, 0, backoff, 0});
    wait(backoff);
    backoff = std::min(2 * backoff, options_.reconnect_max_s);
  }
  ended_ = true;
  cv_.notify_all();
}

std::string IngestClient::Session(int fd) {
  // Reads n bytes, polling so that Stop() is honoured; `started` says a message is
  // already under way (so a close is a truncation and silence a stall).
  auto read = [&](std::uint8_t* p, std::size_t n, bool started) {
    std::size_t total = 0;
    auto last_progress = Steady::now();
    while (total < n) {
      if (stop_) return ReadStatus::kStopped;
      std::size_t got = 0;
      const tcp::IoResult r = tcp::ReadExact(fd, p + total, n - total, kPollMs, got);
      total += got;
      if (got > 0) last_progress = Steady::now();
      if (r == tcp::IoResult::kOk) break;
      const bool mid = started || total > 0;
      if (r == tcp::IoResult::kTimeout) {
        if (mid && MsSince(last_progress) > options_.stall_timeout_ms) return ReadStatus::kStalled;
        continue;
      }
      if (r == tcp::IoResult::kClosed)
        return mid ? ReadStatus::kTruncated : ReadStatus::kClosedClean;
      return ReadStatus::kError;
    }
    std::lock_guard lock(mutex_);
    stats_.bytes += static_cast<std::int64_t>(n);
    return ReadStatus::kOk;
  };
  std::string why = "stopped";  // why the session ended
  // Maps a failed read to its rejection; true when the session must end.
  auto failed = [&](ReadStatus s) {
    switch (s) {
      case ReadStatus::kOk:
        return false;
      case ReadStatus::kClosedClean:
        why = "closed by the server";
        break;
      case ReadStatus::kTruncated:
        Reject("truncated_message");
        why = "closed by the server in the middle of a message";
        break;
      case ReadStatus::kStalled:
        Reject("stalled");
        why = "no data for " + std::to_string(options_.stall_timeout_ms) +
              " ms in the middle of a message";
        break;
      case ReadStatus::kError:
        Reject("socket_error");
        why = "socket error";
        break;
      default:
        break;
    }
    return true;
  };
  std::vector<std::uint8_t> scratch(64 << 10);
  // Reads and discards n bytes, folding them into *crc when given.
  auto discard = [&](std::uint64_t n, std::uint64_t* crc) {
    while (n > 0) {
      const std::size_t chunk =
          static_cast<std::size_t>(std::min<std::uint64_t>(n, scratch.size()));
      const ReadStatus s = read(scratch.data(), chunk, true);
      if (s != ReadStatus::kOk) return s;
      if (crc) *crc = Crc64Ecma182({scratch.data(), chunk}, *crc);
      n -= chunk;
    }
    return ReadStatus::kOk;
  };

  const DecodeLimits& limits = options_.limits;
  while (!stop_) {
    std::uint8_t header_bytes[kHeaderBytes];
    if (failed(read(header_bytes, kHeaderBytes, false))) return why;
    const auto t_header = Steady::now();
    MessageHeader header;
    try {
      header = ParseHeader(header_bytes, limits);
    } catch (const MessageError& e) {
      Reject(e.reason());  // framing can no longer be trusted: reconnect
      why = std::string("bad message header (") + e.reason() + ")";
      return why;
    }
    if (header.type != "IMAGE") {
      std::uint64_t crc = 0;
      if (failed(discard(header.body_size, &crc))) return why;
      if (limits.verify_crc && crc != header.crc) {
        Reject("bad_crc");
      } else {
        std::lock_guard lock(mutex_);
        ++stats_.skipped;
        ++stats_.skipped_by_type[header.type];
      }
      continue;
    }
    std::uint8_t image_bytes[kImageHeaderBytes];
    const auto image_size =
        static_cast<std::size_t>(std::min<std::uint64_t>(header.body_size, kImageHeaderBytes));
    if (failed(read(image_bytes, image_size, true))) return why;
    ImageHeader image;
    try {
      image = ParseImageHeader(header, {image_bytes, image_size}, limits);
    } catch (const MessageError& e) {
      // The header's body_size is within limits, so the stream stays in step: skip it.
      if (failed(discard(header.body_size - image_size, nullptr))) return why;
      Reject(e.reason());
      continue;
    }
    Volume volume = MakeVolume(header, image);
    if (failed(read(volume.voxels().data(), image.voxel_bytes, true))) return why;
    if (limits.verify_crc) {
      std::uint64_t crc = Crc64Ecma182({image_bytes, kImageHeaderBytes});
      crc = Crc64Ecma182(volume.voxels(), crc);
      if (crc != header.crc) {
        Reject("bad_crc");
        continue;
      }
    }
    IngestedFrame f{SourceFrame{std::move(volume), std::nullopt}, header.device_name, 0.0, 0.0,
                    std::nullopt};
    f.arrival_s = WallClockSeconds();
    f.receive_ms = MsSince(t_header);
    const double latency_s = f.arrival_s - header.timestamp_s();
    const bool shared =
        options_.clock == IngestOptions::Clock::kShared ||
        (options_.clock == IngestOptions::Clock::kAuto && std::abs(latency_s) < 60.0);
    if (shared) f.latency_ms = latency_s * 1e3;
    Accept(std::move(f));
  }
  return why;
}

}  // namespace echoservo::imaging::openigtlink
