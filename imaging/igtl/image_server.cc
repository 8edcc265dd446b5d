#include "imaging/igtl/image_server.h"

#include <sys/socket.h>
#include <unistd.h>

#include <chrono>

#include "imaging/igtl/tcp.h"

namespace echoservo::imaging::openigtlink {

struct ImageServer::Client {
  tcp::Fd fd;
};

namespace {}  // namespace

ImageServer::ImageServer(VolumeSource& source, ImageServerOptions options)
    : source_(source), options_(std::move(options)) {}

ImageServer::~ImageServer() { Stop(); }

void ImageServer::Start() {
  int bound = 0;
  tcp::Fd listener = tcp::Listen(options_.bind_address, options_.port, bound);
  port_ = bound;
  listen_fd_ = listener.release();
  accept_thread_ = std::thread([this] { AcceptLoop(); });
  stream_thread_ = std::thread([this] { StreamLoop(); });
}

void ImageServer::Stop() {
  stop_ = true;
  cv_.notify_all();
  if (accept_thread_.joinable()) accept_thread_.join();
  if (stream_thread_.joinable()) stream_thread_.join();
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    listen_fd_ = -1;
  }
  std::lock_guard lock(mutex_);
  clients_.clear();
  stats_.clients_now = 0;
}

void ImageServer::Wait() {
  std::unique_lock lock(mutex_);
  cv_.wait(lock, [this] { return finished_.load() || stop_.load(); });
}

ImageServerStats ImageServer::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

void ImageServer::AcceptLoop() {
  const tcp::Fd listener(::dup(listen_fd_));
  while (!stop_ && !finished_) {
    tcp::Fd fd = tcp::Accept(listener, 100);
    if (!fd.valid()) continue;
    tcp::SetNoDelay(fd.get());
    auto client = std::make_unique<Client>();
    client->fd = std::move(fd);
    std::lock_guard lock(mutex_);
    clients_.push_back(std::move(client));
    ++stats_.clients_accepted;
    stats_.clients_now = static_cast<int>(clients_.size());
    cv_.notify_all();
  }
}

void ImageServer::StreamLoop() {
  {
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [this] {
      return stop_.load() || static_cast<int>(clients_.size()) >= options_.min_clients;
    });
  }
  double rate = options_.rate_hz.value_or(source_.nominal_rate_hz());
  if (!(rate > 0.0)) rate = 0.0;
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  auto next_time = start;
  const auto period =
      rate > 0.0
          ? std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rate))
          : Clock::duration::zero();
  std::vector<std::uint8_t> buffer;
  double encode_ms_total = 0.0;
  std::int64_t frames = 0;
  while (!stop_) {
    if (options_.max_frames >= 0 && frames >= options_.max_frames) break;
    if (options_.max_duration_s > 0.0 &&
        std::chrono::duration<double>(Clock::now() - start).count() >= options_.max_duration_s) {
      break;
    }
    std::optional<SourceFrame> frame = source_.Next();
    if (!frame) break;
    if (rate > 0.0) {
      std::this_thread::sleep_until(next_time);
      next_time += period;
      if (next_time < Clock::now() - 4 * period) next_time = Clock::now();  // fell behind
    }
    const auto t0 = Clock::now();
    if (options_.timestamps == ImageServerOptions::Timestamps::kSendTime) {
      frame->volume.set_timestamp_s(WallClockSeconds());
    }
    EncodeImage(frame->volume, options_.encode, buffer);
    encode_ms_total += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    ++frames;

    // Snapshot the clients; write outside the lock so accepting is never blocked.
    std::vector<Client*> targets;
    {
      std::lock_guard lock(mutex_);
      for (auto& c : clients_) targets.push_back(c.get());
    }
    std::vector<Client*> failed;
    std::int64_t written = 0, stalled = 0;
    for (Client* c : targets) {
      const tcp::IoResult result =
          tcp::WriteAll(c->fd.get(), buffer.data(), buffer.size(), options_.send_timeout_ms);
      if (result == tcp::IoResult::kOk) {
        ++written;
      } else {
        if (result == tcp::IoResult::kTimeout) ++stalled;
        failed.push_back(c);
      }
    }
    std::lock_guard lock(mutex_);
    stats_.frames_sent = frames;
    stats_.messages_written += written;
    stats_.bytes_written += written * static_cast<std::int64_t>(buffer.size());
    stats_.encode_ms_mean = encode_ms_total / static_cast<double>(frames);
    if (written == 0) ++stats_.frames_unsent;
    for (Client* f : failed)
      std::erase_if(clients_, [f](const std::unique_ptr<Client>& c) { return c.get() == f; });
    stats_.clients_stalled += stalled;
    stats_.clients_disconnected += static_cast<std::int64_t>(failed.size()) - stalled;
    stats_.clients_now = static_cast<int>(clients_.size());
  }
  {
    // End of stream: close every connection so clients see it.
    std::lock_guard lock(mutex_);
    for (auto& c : clients_) ::shutdown(c->fd.get(), SHUT_WR);
    finished_ = true;
  }
  cv_.notify_all();
}

}  // namespace echoservo::imaging::openigtlink
