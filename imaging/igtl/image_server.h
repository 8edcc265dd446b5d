// OpenIGTLink scanner server: serves the frames of any imaging::VolumeSource as IMAGE
// messages over TCP to every connected client (one or more), paced at the source's
// nominal rate, a given rate, or as fast as possible. Each frame is encoded once (see
// image_message.h for the wire mapping) and written to all clients; a client that closes or
// errors (disconnected) or stalls longer than send_timeout_ms (cut off) is removed and
// counted, the others go on.
// New clients may connect at any time and get frames from the next one on.
//
// Threads: Start() launches an accept thread and a streaming thread; the source is only
// touched by the streaming thread. Stop() (or the destructor) ends both; Wait() returns
// when the stream has ended (source exhausted, max_frames sent, or Stop()).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "imaging/igtl/image_message.h"
#include "imaging/volume_source.h"

namespace echoservo::imaging::openigtlink {

struct ImageServerOptions {
  std::string bind_address = "127.0.0.1";  // "0.0.0.0" to serve other hosts
  int port = 0;                            // 0: an ephemeral port (see ImageServer::port())
  // Frames per second: nullopt = the source's nominal rate (as fast as possible when it
  // has none), 0 = as fast as possible, > 0 = this rate.
  std::optional<double> rate_hz;
  // Timestamps written to the header: the volume's own (kSource), or the wall clock
  // (seconds since the Unix epoch) when the frame is sent (kSendTime) — what a live
  // scanner does, and what lets a client on the same clock measure latency.
  enum class Timestamps { kSource, kSendTime };
  Timestamps timestamps = Timestamps::kSource;
  EncodeOptions encode;
  int min_clients = 1;           // pull no frame before this many clients are connected
  std::int64_t max_frames = -1;  // < 0: until the source ends
  double max_duration_s = 0;     // > 0: stop streaming after this long
  int send_timeout_ms = 2000;    // a client accepting no byte for this long is dropped
};

struct ImageServerStats {
  std::int64_t frames_sent = 0;       // frames pulled from the source and broadcast
  std::int64_t messages_written = 0;  // frames × clients that got them whole
  std::int64_t bytes_written = 0;
  std::int64_t clients_accepted = 0;
  // Clients that left: the peer closed the connection or a write failed (a client that
  // exits or disconnects mid-stream). Not frames lost: see frames_unsent.
  std::int64_t clients_disconnected = 0;
  // Clients cut off by the server because they accepted no byte for send_timeout_ms.
  std::int64_t clients_stalled = 0;
  // Frames pulled from the source that no client received whole (none connected, or every
  // write failed): the frames the stream dropped.
  std::int64_t frames_unsent = 0;
  int clients_now = 0;
  double encode_ms_mean = 0;  // encode + CRC per frame
};

class ImageServer {
 public:
  // `source` must outlive the server.
  ImageServer(VolumeSource& source, ImageServerOptions options);
  ~ImageServer();
  ImageServer(const ImageServer&) = delete;
  ImageServer& operator=(const ImageServer&) = delete;

  // Binds and starts serving; throws std::runtime_error when the port cannot be bound.
  void Start();
  int port() const { return port_; }
  // Ends streaming and closes every connection. Idempotent.
  void Stop();
  // Blocks until the stream has ended.
  void Wait();
  bool finished() const { return finished_; }
  ImageServerStats stats() const;

 private:
  struct Client;
  void AcceptLoop();
  void StreamLoop();

  VolumeSource& source_;
  ImageServerOptions options_;
  int port_ = 0;
  int listen_fd_ = -1;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<std::unique_ptr<Client>> clients_;
  ImageServerStats stats_;
  std::thread accept_thread_;
  std::thread stream_thread_;
};

}  // namespace echoservo::imaging::openigtlink
