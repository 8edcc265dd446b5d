#include "imaging/igtl/ingest.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "imaging/igtl/client_connection.h"
#include "imaging/igtl/crc64.h"

namespace echoservo::imaging::openigtlink {
namespace {

using Steady = std::chrono::steady_clock;

double MsSince(Steady::time_point t) {
  return std::chrono::duration<double, std::milli>(Steady::now() - t).count();
}

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
  ReconnectHooks hooks;
  hooks.connect_failed = [this](const std::string& error) {
    std::lock_guard lock(mutex_);
    ++stats_.connect_failures;
    stats_.last_connect_error = error;
  };
  hooks.connected = [this] {
    std::lock_guard lock(mutex_);
    ++stats_.connections;
  };
  hooks.session = [this](int fd) { return Session(fd); };
  hooks.progress = [this] {
    std::lock_guard lock(mutex_);
    return stats_.frames + stats_.skipped;
  };
  hooks.frames = [this] {
    std::lock_guard lock(mutex_);
    return stats_.frames;
  };
  if (options_.on_event) {  // called in place, not copied: its state stays the caller's
    hooks.on_event = [this](const ConnectionEvent& e) { options_.on_event(e); };
  }
  hooks.wait = [this](double s) { WaitUnlessStopped(mutex_, cv_, stop_, s); };
  RunReconnectLoop(
      {options_.host, options_.port, options_.connect_timeout_ms, options_.reconnect_initial_s,
       options_.reconnect_max_s, options_.max_connect_failures},
      stop_, hooks);
  ended_ = true;
  cv_.notify_all();
}

std::string IngestClient::Session(int fd) {
  // Reads poll so that Stop() is honoured (client_connection.h); a failed one is counted
  // as a rejection and ends the session (reader.why() says why).
  SessionReader reader(
      fd, stop_, options_.stall_timeout_ms,
      [this](std::size_t n) {
        std::lock_guard lock(mutex_);
        stats_.bytes += static_cast<std::int64_t>(n);
      },
      [this](const std::string& reason) { Reject(reason); });
  std::vector<std::uint8_t> scratch(64 << 10);
  // Reads and discards n bytes, folding them into *crc when given.
  auto discard = [&](std::uint64_t n, std::uint64_t* crc) {
    while (n > 0) {
      const std::size_t chunk =
          static_cast<std::size_t>(std::min<std::uint64_t>(n, scratch.size()));
      if (!reader.Read(scratch.data(), chunk, true)) return false;
      if (crc) *crc = Crc64Ecma182({scratch.data(), chunk}, *crc);
      n -= chunk;
    }
    return true;
  };

  const DecodeLimits& limits = options_.limits;
  while (!stop_) {
    std::uint8_t header_bytes[kHeaderBytes];
    if (!reader.Read(header_bytes, kHeaderBytes, false)) return reader.why();
    const auto t_header = Steady::now();
    MessageHeader header;
    try {
      header = ParseHeader(header_bytes, limits);
    } catch (const MessageError& e) {
      Reject(e.reason());  // framing can no longer be trusted: reconnect
      return std::string("bad message header (") + e.reason() + ")";
    }
    if (header.type != "IMAGE") {
      std::uint64_t crc = 0;
      if (!discard(header.body_size, &crc)) return reader.why();
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
    if (!reader.Read(image_bytes, image_size, true)) return reader.why();
    ImageHeader image;
    try {
      image = ParseImageHeader(header, {image_bytes, image_size}, limits);
    } catch (const MessageError& e) {
      // The header's body_size is within limits, so the stream stays in step: skip it.
      if (!discard(header.body_size - image_size, nullptr)) return reader.why();
      Reject(e.reason());
      continue;
    }
    Volume volume = MakeVolume(header, image);
    if (!reader.Read(volume.voxels().data(), image.voxel_bytes, true)) return reader.why();
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
  return reader.why();
}

}  // namespace echoservo::imaging::openigtlink
