#include "imaging/igtl/detection_server.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>

#include "imaging/igtl/tcp.h"
#include "imaging/igtl/tracking_messages.h"

namespace echoservo::imaging::openigtlink {
namespace detection_server_internal {

// Outside the anonymous namespace: DetectionServer::Message (external linkage) holds one.
enum class Kind { kImage, kTransform, kPoints, kStatus };

namespace {

double SteadyMs() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

constexpr std::size_t kLatencyRing = 4096;
constexpr std::size_t kClientHistory = 256;

void PatchTimestamp(std::vector<std::uint8_t>& message, double timestamp_s) {
  const std::uint64_t t = SecondsToIgtlTimestamp(timestamp_s);
  for (int b = 0; b < 8; ++b) message[34 + b] = static_cast<std::uint8_t>(t >> (56 - 8 * b));
}

std::string PeerName(int fd) {
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0 ||
      addr.sin_family != AF_INET) {
    return "?";
  }
  char text[INET_ADDRSTRLEN] = {};
  ::inet_ntop(AF_INET, &addr.sin_addr, text, sizeof text);
  return std::string(text) + ":" + std::to_string(ntohs(addr.sin_port));
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

}  // namespace
}  // namespace detection_server_internal

struct DetectionServer::Message {
  detection_server_internal::Kind kind;
  std::vector<std::uint8_t> bytes;
  double published_ms = 0.0;  // steady clock of the Publish() call
};

struct DetectionServer::Pending {
  DetectionSample sample;
  std::shared_ptr<Volume> volume;  // a slot, or null
  double published_ms = 0.0;
};

struct DetectionServer::Client {
  tcp::Fd fd;
  std::size_t stats_index = 0;  // into stats_.clients (under mutex_)
  std::deque<std::shared_ptr<const Message>> queue;
  std::size_t queued_bytes = 0;
  std::size_t offset = 0;         // bytes of queue.front() already written
  double last_progress_ms = 0.0;  // a byte written, or the queue became non-empty
  std::uint8_t header[kHeaderBytes] = {};
  std::size_t header_have = 0;
  std::uint64_t body_left = 0;  // body bytes of an incoming message still to discard
  bool closed = false;
};

void DetectionServerOptions::Validate() const {
  const auto fail = [](const std::string& why) {
    throw std::invalid_argument("DetectionServerOptions: " + why);
  };
  if (port < 0 || port > 65535) fail("port " + std::to_string(port) + " is outside [0, 65535]");
  if (bind_address.empty()) fail("bind address is empty");
  for (const std::string* name : {&transform_name, &points_name, &status_name, &image_name}) {
    if (name->empty() || name->size() > 20) {
      fail("device name '" + *name + "' must have 1 to 20 bytes");
    }
  }
  if (client_queue_messages < 1) fail("client_queue_messages must be ≥ 1");
  if (client_queue_bytes < 1) fail("client_queue_bytes must be ≥ 1");
  if (stall_timeout_ms < 1) fail("stall_timeout_ms must be ≥ 1");
  if (pending_samples < 1) fail("pending_samples must be ≥ 1");
  if (socket_send_buffer_bytes < 0) fail("socket_send_buffer_bytes must be ≥ 0");
  if (max_clients < 1) fail("max_clients must be ≥ 1");
  if (thread_nice < 0 || thread_nice > 19) fail("thread_nice must be in [0, 19]");
}

DetectionServer::DetectionServer(DetectionServerOptions options) : o_(std::move(options)) {
  o_.Validate();
}

DetectionServer::~DetectionServer() { Stop(); }

void DetectionServer::Start() {
  if (thread_.joinable()) return;
  int bound = 0;
  tcp::Fd listener = tcp::Listen(o_.bind_address, o_.port, bound);
  const int flags = ::fcntl(listener.get(), F_GETFL, 0);
  ::fcntl(listener.get(), F_SETFL, flags | O_NONBLOCK);
  const int wake = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wake < 0) throw std::runtime_error("DetectionServer: eventfd failed");
  port_ = bound;
  listen_fd_ = listener.release();
  wake_fd_ = wake;
  thread_ = std::thread([this] { Run(); });
}

void DetectionServer::Stop() {
  stop_ = true;
  if (wake_fd_ >= 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const auto n = ::write(wake_fd_, &one, sizeof one);
  }
  if (thread_.joinable()) thread_.join();
  for (auto& c : clients_) CloseClient(*c, "stopped");
  clients_.clear();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  if (wake_fd_ >= 0) ::close(wake_fd_);
  listen_fd_ = wake_fd_ = -1;
  std::lock_guard lock(mutex_);
  stats_.clients_now = 0;
}

void DetectionServer::Publish(const DetectionSample& sample, const Volume* volume) {
  Pending p;
  p.sample = sample;
  p.published_ms = detection_server_internal::SteadyMs();
  if (o_.send_volumes && volume != nullptr) {
    {
      // A slot only the pool holds; taking it makes its use count 2, so no other caller
      // picks it, and the server thread only ever releases slots.
      std::lock_guard lock(pending_mutex_);
      for (auto& slot : slots_) {
        if (slot.use_count() == 1) {
          p.volume = slot;
          break;
        }
      }
    }
    if (p.volume) {
      *p.volume = *volume;  // reuses the slot's voxel buffer when the size matches
    } else {
      p.volume = std::make_shared<Volume>(*volume);
      std::lock_guard lock(pending_mutex_);
      slots_.push_back(p.volume);
      ++slots_allocated_;
    }
  }
  {
    std::lock_guard lock(pending_mutex_);
    ++published_;
    if (pending_.size() >= o_.pending_samples) {
      pending_.pop_front();
      ++pending_dropped_;
    }
    pending_.push_back(std::move(p));
  }
  if (wake_fd_ >= 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const auto n = ::write(wake_fd_, &one, sizeof one);
  }
}

DetectionServerStats DetectionServer::stats() const {
  DetectionServerStats s;
  {
    std::lock_guard lock(mutex_);
    s = stats_;
  }
  {
    std::lock_guard lock(pending_mutex_);
    s.samples_published = published_;
    s.samples_dropped = pending_dropped_;
    s.volume_slots_allocated = slots_allocated_;
  }
  std::lock_guard lock(mutex_);
  using detection_server_internal::Percentile;
  s.send_latency_ms_p50 = Percentile(latencies_ms_, 0.5);
  s.send_latency_ms_p99 = Percentile(latencies_ms_, 0.99);
  s.send_latency_ms_max =
      latencies_ms_.empty() ? 0.0 : *std::max_element(latencies_ms_.begin(), latencies_ms_.end());
  return s;
}

void DetectionServer::EncodeSample(const Pending& pending,
                                   std::vector<std::shared_ptr<const Message>>& out) {
  using detection_server_internal::Kind;
  const DetectionSample& s = pending.sample;
  const double t = s.acquired_unix_s;
  // LPS (echoservo) → the wire's frame.
  const Eigen::Vector3d flip = o_.coordinate_system == CoordinateSystem::kRas
                                   ? Eigen::Vector3d(-1, -1, 1)
                                   : Eigen::Vector3d(1, 1, 1);
  const auto make = [&](Kind kind) {
    auto m = std::make_shared<Message>();
    m->kind = kind;
    m->published_ms = pending.published_ms;
    return m;
  };
  std::vector<std::shared_ptr<const Message>> msgs;
  if (pending.volume) {
    // An IMAGE buffer no client queue holds any more (~5 MB: no allocation and page faults
    // per volume once the pool has as many as are in flight).
    std::shared_ptr<Message> m;
    for (auto& buffer : image_pool_) {
      if (buffer.use_count() == 1) {
        m = buffer;
        break;
      }
    }
    if (!m) {
      m = std::make_shared<Message>();
      image_pool_.push_back(m);
    }
    m->kind = Kind::kImage;
    m->published_ms = pending.published_ms;
    EncodeOptions eo;
    eo.device_name = o_.image_name;
    eo.coordinate_system = o_.coordinate_system;
    EncodeImage(*pending.volume, eo, m->bytes);
    // The acquisition time, not the slot's own stamp (the header is outside the CRC).
    detection_server_internal::PatchTimestamp(m->bytes, t);
    msgs.push_back(std::move(m));
  }
  if (s.found) {
    const Eigen::Vector3d tip = flip.cwiseProduct(s.tip_mm);
    auto tm = make(Kind::kTransform);
    EncodeTransform(o_.transform_name, t, CatheterFrame(tip, flip.cwiseProduct(s.axis)), tm->bytes);
    msgs.push_back(std::move(tm));
    std::vector<IgtlPoint> points(1);
    points[0].name = "CatheterTip";
    points[0].group = "Detections";
    points[0].rgba = {255, 255, 0, 255};
    points[0].position_mm = tip;
    points[0].radius_mm = 1.0;
    if (s.target_mm) {
      IgtlPoint target;
      target.name = "Target";
      target.group = "Detections";
      target.rgba = {255, 0, 0, 255};
      target.position_mm = flip.cwiseProduct(*s.target_mm);
      target.radius_mm = 1.0;
      points.push_back(target);
    }
    auto pm = make(Kind::kPoints);
    EncodePoints(o_.points_name, t, points, pm->bytes);
    msgs.push_back(std::move(pm));
  }
  if (!s.found || lost_) {  // lost, or found again after a loss
    IgtlStatus st;
    if (s.found) {
      st.code = static_cast<std::uint16_t>(StatusCode::kOk);
      st.message = "catheter found again";
    } else {
      st.code = static_cast<std::uint16_t>(StatusCode::kNotFound);
      st.error_name = "NOT_DETECTED";
      st.message = "catheter not detected in this volume";
    }
    auto sm = make(Kind::kStatus);
    EncodeStatus(o_.status_name, t, st, sm->bytes);
    msgs.push_back(std::move(sm));
  }
  // Only now (nothing threw): the sample's messages and the found/lost state.
  lost_ = !s.found;
  for (auto& m : msgs) out.push_back(std::move(m));
}

void DetectionServer::AcceptClients() {
  for (;;) {
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) return;  // EAGAIN: none left (or an error: retried on the next poll)
    tcp::Fd owned(fd);
    std::lock_guard lock(mutex_);
    if (static_cast<int>(clients_.size()) >= o_.max_clients) {
      ++stats_.clients_refused;
      continue;  // closed by owned's destructor
    }
    tcp::SetNoDelay(fd);
    if (o_.socket_send_buffer_bytes > 0) {
      ::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &o_.socket_send_buffer_bytes,
                   sizeof o_.socket_send_buffer_bytes);
    }
    auto c = std::make_unique<Client>();
    c->fd = std::move(owned);
    DetectionClientStats cs;
    cs.id = next_client_id_++;
    cs.peer = detection_server_internal::PeerName(fd);
    if (stats_.clients.size() >= detection_server_internal::kClientHistory) {
      // Forget the oldest departed client; indices of live clients shift by one.
      const auto it = std::find_if(stats_.clients.begin(), stats_.clients.end(),
                                   [](const DetectionClientStats& x) { return !x.connected; });
      if (it != stats_.clients.end()) {
        const auto removed = static_cast<std::size_t>(it - stats_.clients.begin());
        stats_.clients.erase(it);
        for (auto& other : clients_) {
          if (other->stats_index > removed) --other->stats_index;
        }
      }
    }
    c->stats_index = stats_.clients.size();
    stats_.clients.push_back(cs);
    ++stats_.clients_accepted;
    clients_.push_back(std::move(c));
    stats_.clients_now = static_cast<int>(clients_.size());
  }
}

// Under mutex_ (stats).
void DetectionServer::Enqueue(Client& c, const std::shared_ptr<const Message>& m) {
  if (c.queue.empty()) c.last_progress_ms = detection_server_internal::SteadyMs();
  c.queue.push_back(m);
  c.queued_bytes += m->bytes.size();
  // Drop the oldest messages not being written until the queue fits (the one in progress
  // stays: the stream must stay framed).
  while (c.queue.size() > 1 &&
         (c.queue.size() > o_.client_queue_messages || c.queued_bytes > o_.client_queue_bytes)) {
    const std::size_t victim = c.offset > 0 ? 1 : 0;
    if (victim >= c.queue.size() - 1) break;  // never drop the message just queued
    c.queued_bytes -= c.queue[victim]->bytes.size();
    c.queue.erase(c.queue.begin() + static_cast<std::ptrdiff_t>(victim));
    ++stats_.messages_dropped;
    ++stats_.clients[c.stats_index].messages_dropped;
  }
}

// Writes what the socket takes. False when the client must go (error).
bool DetectionServer::WriteClient(Client& c, double now_ms) {
  using detection_server_internal::Kind;
  while (!c.queue.empty()) {
    const Message& m = *c.queue.front();
    const std::size_t left = m.bytes.size() - c.offset;
    const ssize_t n = ::send(c.fd.get(), m.bytes.data() + c.offset, left, MSG_NOSIGNAL);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
      if (errno == EINTR) continue;
      return false;
    }
    c.last_progress_ms = now_ms;
    c.offset += static_cast<std::size_t>(n);
    std::lock_guard lock(mutex_);
    stats_.bytes_sent += static_cast<std::uint64_t>(n);
    stats_.clients[c.stats_index].bytes_sent += static_cast<std::uint64_t>(n);
    if (c.offset < m.bytes.size()) continue;
    const double done_ms = detection_server_internal::SteadyMs();
    if (latencies_ms_.size() < detection_server_internal::kLatencyRing) {
      latencies_ms_.push_back(done_ms - m.published_ms);
    } else {
      latencies_ms_[latency_next_] = done_ms - m.published_ms;
    }
    latency_next_ = (latency_next_ + 1) % detection_server_internal::kLatencyRing;
    switch (m.kind) {
      case Kind::kImage:
        ++stats_.sent_image;
        break;
      case Kind::kTransform:
        ++stats_.sent_transform;
        break;
      case Kind::kPoints:
        ++stats_.sent_points;
        break;
      case Kind::kStatus:
        ++stats_.sent_status;
        break;
    }
    ++stats_.clients[c.stats_index].messages_sent;
    c.queued_bytes -= m.bytes.size();
    c.queue.pop_front();
    c.offset = 0;
  }
  return true;
}

// Reads and discards what the client sent, validating headers. False when it must go; the
// reason is then set in its stats.
bool DetectionServer::ReadClient(Client& c) {
  std::uint8_t buf[16384];
  for (;;) {
    const ssize_t n = ::recv(c.fd.get(), buf, sizeof buf, 0);
    if (n == 0) {
      CloseClient(c, "closed");
      return false;
    }
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
      if (errno == EINTR) continue;
      CloseClient(c, "error");
      return false;
    }
    std::size_t at = 0;
    const auto got = static_cast<std::size_t>(n);
    while (at < got) {
      if (c.body_left > 0) {
        const std::size_t take = static_cast<std::size_t>(
            std::min<std::uint64_t>(c.body_left, static_cast<std::uint64_t>(got - at)));
        c.body_left -= take;
        at += take;
        if (c.body_left == 0) {
          std::lock_guard lock(mutex_);
          ++stats_.client_messages_received;
          ++stats_.clients[c.stats_index].messages_received;
        }
        continue;
      }
      const std::size_t take = std::min(kHeaderBytes - c.header_have, got - at);
      std::memcpy(c.header + c.header_have, buf + at, take);
      c.header_have += take;
      at += take;
      if (c.header_have < kHeaderBytes) continue;
      c.header_have = 0;
      DecodeLimits limits;
      limits.max_body_bytes = o_.max_client_body_bytes;
      try {
        const MessageHeader h = ParseHeader({c.header, kHeaderBytes}, limits);
        c.body_left = h.body_size;
        if (c.body_left == 0) {
          std::lock_guard lock(mutex_);
          ++stats_.client_messages_received;
          ++stats_.clients[c.stats_index].messages_received;
        }
      } catch (const MessageError& e) {
        {
          std::lock_guard lock(mutex_);
          ++stats_.client_messages_rejected;
        }
        CloseClient(c, e.reason());  // cannot resynchronise after a garbage header
        return false;
      }
    }
  }
}

void DetectionServer::CloseClient(Client& c, const std::string& end) {
  if (c.closed) return;
  c.closed = true;
  c.fd.reset();
  std::lock_guard lock(mutex_);
  DetectionClientStats& cs = stats_.clients[c.stats_index];
  cs.connected = false;
  cs.end = end;
  if (end == "stalled") {
    ++stats_.clients_stalled;
  } else if (end != "stopped") {
    ++stats_.clients_disconnected;
  }
}

void DetectionServer::Run() {
  using detection_server_internal::SteadyMs;
  if (o_.thread_nice > 0) {
    // Linux: a thread's own nice value (setpriority on its thread id). Lowering one's own
    // priority needs no privilege; a failure leaves it as it was.
    [[maybe_unused]] const int rc =
        ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), o_.thread_nice);
  }
  std::vector<pollfd> fds;
  std::deque<Pending> work;
  std::vector<std::shared_ptr<const Message>> messages;
  while (!stop_) {
    fds.clear();
    fds.push_back({wake_fd_, POLLIN, 0});
    fds.push_back({listen_fd_, POLLIN, 0});
    for (const auto& c : clients_) {
      fds.push_back(
          {c->fd.get(), static_cast<short>(POLLIN | (c->queue.empty() ? 0 : POLLOUT)), 0});
    }
    const int ready = ::poll(fds.data(), fds.size(), 50);
    if (stop_) break;
    if (ready < 0 && errno != EINTR) break;
    if (fds[0].revents & POLLIN) {
      std::uint64_t count = 0;
      [[maybe_unused]] const auto n = ::read(wake_fd_, &count, sizeof count);
    }
    if (fds[1].revents & POLLIN) AcceptClients();
    {
      std::lock_guard lock(pending_mutex_);
      work.swap(pending_);
    }
    messages.clear();
    for (const Pending& p : work) {
      try {
        EncodeSample(p, messages);
        std::lock_guard lock(mutex_);
        ++stats_.samples_encoded;
      } catch (const std::invalid_argument& e) {
        std::lock_guard lock(mutex_);
        ++stats_.encode_errors;
        stats_.last_encode_error = e.what();
      }
    }
    {
      // Releases the volume slots under the lock Publish() picks free slots under: its copy
      // into a slot happens after this thread's last read of it.
      std::lock_guard lock(pending_mutex_);
      work.clear();
    }
    // Keep at most 4 idle IMAGE buffers (a burst that grew the pool gives its memory back).
    std::size_t idle = 0;
    std::erase_if(image_pool_, [&idle](const std::shared_ptr<Message>& b) {
      return b.use_count() == 1 && ++idle > 4;
    });
    const double now_ms = SteadyMs();
    // fds[2 + i] belongs to clients_[i] (clients accepted above are not in fds yet).
    const std::size_t polled = fds.size() - 2;
    for (std::size_t i = 0; i < clients_.size(); ++i) {
      Client& c = *clients_[i];
      if (!messages.empty()) {
        std::lock_guard lock(mutex_);
        for (const auto& m : messages) Enqueue(c, m);
      }
      const short revents = i < polled ? fds[2 + i].revents : 0;
      if ((revents & (POLLIN | POLLHUP | POLLERR)) && !ReadClient(c)) continue;
      if (!c.queue.empty() && !WriteClient(c, now_ms)) {
        CloseClient(c, "error");
        continue;
      }
      if (!c.queue.empty() && SteadyMs() - c.last_progress_ms > o_.stall_timeout_ms) {
        CloseClient(c, "stalled");
      }
    }
    const auto gone = std::erase_if(clients_, [](const auto& c) { return c->closed; });
    if (gone > 0) {
      std::lock_guard lock(mutex_);
      stats_.clients_now = static_cast<int>(clients_.size());
    }
  }
}

}  // namespace echoservo::imaging::openigtlink
