// OpenIGTLink detection server: what the tracker found in each processed volume, served over
// TCP to any number of viewers (3D Slicer's OpenIGTLinkIF is the reference client; see
// docs/slicer.md). Per published volume it sends, in this order:
//   IMAGE     `Image` (only with DetectionServerOptions::send_volumes and a volume given)
//   TRANSFORM `CatheterToImage`: CatheterFrame (z along the axis towards the tip, origin at
//             the tip), when the catheter was found
//   POINT     `Detections`: points `CatheterTip` and, when found, `Target`
//   STATUS    `CatheterToImage`: kNotFound for every volume without a catheter, kOk once on
//             the first volume it is found again
// Frames: samples come in echoservo's image frame (LPS, mm); everything goes out in
// options.coordinate_system, the frame of the IMAGE messages (RAS by default, as
// image_message.h encodes them): LPS → RAS flips the signs of x and y, so that in Slicer the
// catheter overlays the volume with no parent transform.
// Time: every message carries the sample's acquisition time, s since the Unix epoch (the
// caller converts its own clock).
// Threads: Publish() is non-blocking and cheap (a queue push, a copy of the volume into a
// reused slot when volumes are sent); one server thread (at nice 10 by default: it yields the
// CPU to the tracker) accepts, encodes, writes (non-blocking sockets, poll) and reads. Each client
// has a bounded queue (messages and bytes): when full, its oldest unsent message is dropped and
// counted; a client that takes no byte for stall_timeout_ms while it has data queued is
// disconnected and counted. Bytes clients send (Slicer's own TRANSFORMs, GET_/STT_ queries) are
// read, their headers validated and counted, and discarded; a client whose header is garbage is
// disconnected (a stream cannot resynchronise), the others go on. Errors: the constructor throws
// std::invalid_argument for bad options, Start() throws std::runtime_error when the port cannot be
// bound; a sample that cannot be encoded (a non-finite position) is counted and skipped.
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "imaging/igtl/image_message.h"
#include "imaging/volume.h"

namespace echoservo::imaging::openigtlink {

struct DetectionServerOptions {
  std::string bind_address = "127.0.0.1";  // "0.0.0.0" to serve other hosts
  int port = 0;                            // 0: an ephemeral port (see port())
  bool send_volumes = false;               // also an IMAGE per volume (~5 MB each)
  CoordinateSystem coordinate_system = CoordinateSystem::kRas;
  std::string transform_name = "CatheterToImage";
  std::string points_name = "Detections";
  std::string status_name = "CatheterToImage";
  std::string image_name = "Image";
  std::size_t client_queue_messages = 64;             // per client, ≥ 1
  std::size_t client_queue_bytes = 24u << 20;         // per client (24 MiB: ~4 volumes), ≥ 1
  int stall_timeout_ms = 2000;                        // ≥ 1
  std::size_t pending_samples = 8;                    // Publish → server thread, ≥ 1
  int socket_send_buffer_bytes = 1 << 20;             // per client; 0: the system's
  std::uint64_t max_client_body_bytes = 64ull << 20;  // larger incoming bodies: garbage
  int max_clients = 32;                               // more are refused (counted)
  // The server thread's nice value (Linux, per thread; 0: the caller's): it takes the CPU the
  // tracker leaves, so a busy host slows the viewers (their queues drop), not the tracker.
  int thread_nice = 10;
  void Validate() const;  // throws std::invalid_argument
};

// One processed volume, in echoservo's image frame (LPS, mm).
struct DetectionSample {
  double acquired_unix_s = 0.0;  // acquisition time, s since the Unix epoch
  bool found = false;            // catheter found (tip and axis valid)
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // towards the tip
  std::optional<Eigen::Vector3d> target_mm;
  double confidence = 0.0;  // [0, 1]: the CatheterTip point's radius is not scaled by it
};

struct DetectionClientStats {
  std::uint64_t id = 0;
  std::string peer;  // "address:port"
  bool connected = true;
  std::string end;  // why it left: "closed", "stalled", "error", "bad_header", "stopped"
  std::uint64_t messages_sent = 0, messages_dropped = 0, bytes_sent = 0;
  std::uint64_t messages_received = 0;  // whole messages it sent us (discarded)
};

struct DetectionServerStats {
  std::uint64_t samples_published = 0;  // Publish() calls
  // Samples the server thread had not taken when pending_samples newer ones arrived.
  std::uint64_t samples_dropped = 0;
  std::uint64_t samples_encoded = 0, encode_errors = 0;
  std::string last_encode_error;
  std::uint64_t clients_accepted = 0, clients_refused = 0;
  int clients_now = 0;
  std::uint64_t clients_disconnected = 0;  // left: closed, error or bad header
  std::uint64_t clients_stalled = 0;       // cut off: no byte taken for stall_timeout_ms
  // Messages written whole to a client, by type (summed over clients), and bytes.
  std::uint64_t sent_transform = 0, sent_points = 0, sent_status = 0, sent_image = 0;
  std::uint64_t bytes_sent = 0;
  std::uint64_t messages_dropped = 0;  // oldest dropped from a full client queue
  std::uint64_t client_messages_received = 0, client_messages_rejected = 0;
  std::uint64_t volume_slots_allocated = 0;  // volume copies that needed a new buffer
  // Publish() to the message's last byte accepted by a client's socket, over the newest
  // 4096 (message, client) pairs.
  double send_latency_ms_p50 = 0.0, send_latency_ms_p99 = 0.0, send_latency_ms_max = 0.0;
  std::vector<DetectionClientStats> clients;  // every client accepted (the newest 256)
};

class DetectionServer {
 public:
  explicit DetectionServer(DetectionServerOptions options);  // throws std::invalid_argument
  ~DetectionServer();
  DetectionServer(const DetectionServer&) = delete;
  DetectionServer& operator=(const DetectionServer&) = delete;

  // Binds and starts the server thread; throws std::runtime_error when the port cannot be
  // bound.
  void Start();
  int port() const { return port_; }
  // Closes every connection and ends the thread. Idempotent. Messages still queued are lost.
  void Stop();

  // Hands one sample to the server thread; never blocks on a socket and never encodes. With
  // send_volumes and `volume` non-null, the volume is copied into a reused slot (no
  // allocation once the slots exist); its own timestamp is ignored (acquired_unix_s is sent).
  void Publish(const DetectionSample& sample, const Volume* volume = nullptr);

  DetectionServerStats stats() const;

 private:
  struct Client;
  struct Message;
  struct Pending;
  void Run();
  void EncodeSample(const Pending& pending, std::vector<std::shared_ptr<const Message>>& out);
  void AcceptClients();
  void Enqueue(Client& client, const std::shared_ptr<const Message>& message);
  bool WriteClient(Client& client, double now_ms);
  bool ReadClient(Client& client);
  void CloseClient(Client& client, const std::string& end);

  DetectionServerOptions o_;
  int port_ = 0;
  int listen_fd_ = -1;
  int wake_fd_ = -1;  // eventfd: Publish and Stop wake the server thread
  std::atomic<bool> stop_{false};
  std::thread thread_;

  // Publish() takes only pending_mutex_, which the server thread holds just to swap the queue
  // out: the low-priority server thread never holds what the tracker waits for while it
  // writes or counts (priority inversion).
  mutable std::mutex pending_mutex_;  // guards pending_, slots_ and the three counts below
  std::deque<Pending> pending_;
  std::vector<std::shared_ptr<Volume>> slots_;
  std::uint64_t published_ = 0, pending_dropped_ = 0, slots_allocated_ = 0;
  mutable std::mutex mutex_;  // guards stats_ and the latencies
  DetectionServerStats stats_;
  std::vector<double> latencies_ms_;  // ring of the newest 4096
  std::size_t latency_next_ = 0;

  // Server thread only.
  std::vector<std::unique_ptr<Client>> clients_;
  std::uint64_t next_client_id_ = 1;
  std::vector<std::shared_ptr<Message>> image_pool_;  // reused IMAGE buffers
  bool lost_ = false;                                 // the last sample had no catheter
};

}  // namespace echoservo::imaging::openigtlink
