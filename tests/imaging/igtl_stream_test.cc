// OpenIGTLink streaming over loopback (127.0.0.1 only): ImageServer -> IngestClient round
// trip, queue dropping, client disconnects, and bad input from a raw socket (bad CRC,
// size mismatch, too many voxels, unknown types, garbage, oversize and truncated
// messages), each counted with its reason while the stream goes on.
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <thread>

#include "imaging/igtl/crc64.h"
#include "imaging/igtl/image_message.h"
#include "imaging/igtl/image_server.h"
#include "imaging/igtl/ingest.h"
#include "imaging/igtl/phantom_source.h"
#include "imaging/igtl/tcp.h"
#include "tests/imaging/igtl_test_bytes.h"

namespace echoservo::imaging::openigtlink {
namespace {

using namespace std::chrono_literals;

PhantomOptions SmallPhantom(std::int64_t frames) {
  PhantomOptions o;
  o.dims = {40, 30, 20};
  o.spacing_mm = 0.7;
  o.rate_hz = 0;
  o.frame_count = frames;
  return o;
}

IngestOptions Loopback(int port) {
  IngestOptions o;
  o.host = "127.0.0.1";
  o.port = port;
  o.reconnect_initial_s = 0.01;
  o.reconnect_max_s = 0.05;
  o.queue_capacity = 64;
  return o;
}

// Polls `done` for up to `limit`.
template <typename F>
bool WaitFor(F done, std::chrono::milliseconds limit = 5000ms) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(5ms);
  }
  return done();
}

TEST(IgtlStream, ServerToIngestRoundTripIsExact) {
  PhantomSource source(SmallPhantom(12));
  ImageServerOptions so;
  so.rate_hz = 0.0;  // as fast as possible
  ImageServer server(source, so);
  server.Start();
  IngestClient ingest(Loopback(server.port()));
  ingest.Start();

  PhantomSource expected(SmallPhantom(12));
  for (int n = 0; n < 12; ++n) {
    auto got = ingest.NextFrame(5.0);
    ASSERT_TRUE(got) << "frame " << n;
    auto want = expected.Next();
    const Volume& a = got->frame.volume;
    const Volume& b = want->volume;
    EXPECT_EQ(a.dims(), b.dims());
    EXPECT_TRUE(a.spacing_mm().isApprox(b.spacing_mm(), 1e-6));
    EXPECT_LT((a.origin_mm() - b.origin_mm()).norm(), 1e-5);
    EXPECT_LT((a.direction() - b.direction()).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_TRUE(std::equal(a.voxels().begin(), a.voxels().end(), b.voxels().begin())) << n;
    EXPECT_NEAR(a.timestamp_s(), b.timestamp_s(), 1e-9) << n;
    EXPECT_EQ(a.frame_index(), n);
    EXPECT_EQ(got->device_name, "echoservo");
    EXPECT_GE(got->receive_ms, 0.0);
  }
  server.Wait();
  EXPECT_TRUE(server.finished());
  EXPECT_EQ(server.stats().frames_sent, 12);
  const IngestStats s = ingest.stats();
  EXPECT_EQ(s.frames, 12);
  EXPECT_EQ(s.rejected, 0);
  EXPECT_EQ(s.dropped, 0);
  EXPECT_EQ(s.receive.count, 12);
  EXPECT_EQ(s.latency.count, 0);  // phantom time (~0 s) is not on the wall clock
}

TEST(IgtlStream, SendTimeStampsGiveLatencyAndFullQueueDropsOldest) {
  PhantomSource source(SmallPhantom(10));
  ImageServerOptions so;
  so.rate_hz = 0.0;
  so.timestamps = ImageServerOptions::Timestamps::kSendTime;
  ImageServer server(source, so);
  server.Start();
  IngestOptions io = Loopback(server.port());
  io.queue_capacity = 2;
  IngestClient ingest(io);
  ingest.Start();
  server.Wait();
  ASSERT_TRUE(WaitFor([&] { return ingest.stats().frames == 10; }));
  const IngestStats s = ingest.stats();
  EXPECT_EQ(s.dropped, 8);
  EXPECT_EQ(s.latency.count, 10);
  EXPECT_GE(s.latency.p50_ms, 0.0);
  EXPECT_LT(s.latency.p99_ms, 1000.0);
  auto a = ingest.NextFrame(1.0), b = ingest.NextFrame(1.0);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->frame.volume.frame_index(), 8);  // the latest two are kept
  EXPECT_EQ(b->frame.volume.frame_index(), 9);
  EXPECT_FALSE(ingest.NextFrame(0.05));
}

TEST(IgtlStream, ServerKeepsServingWhenOneOfTwoClientsLeaves) {
  PhantomSource source(SmallPhantom(40));
  ImageServerOptions so;
  so.rate_hz = 200.0;
  so.min_clients = 2;
  ImageServer server(source, so);
  server.Start();
  IngestClient stays(Loopback(server.port()));
  auto leaves = std::make_unique<IngestClient>(Loopback(server.port()));
  stays.Start();
  leaves->Start();
  ASSERT_TRUE(leaves->NextFrame(5.0));
  leaves.reset();  // disconnects mid-stream
  server.Wait();
  ASSERT_TRUE(WaitFor([&] { return stays.stats().frames == 40; }));
  EXPECT_EQ(server.stats().frames_sent, 40);
  // The client that left is counted as disconnected, not as stalled, and no frame was lost:
  // every one reached the client that stayed.
  EXPECT_EQ(server.stats().clients_disconnected, 1);
  EXPECT_EQ(server.stats().clients_stalled, 0);
  EXPECT_EQ(server.stats().frames_unsent, 0);
  EXPECT_EQ(stays.stats().rejected, 0);
}

// A raw server that plays scripted connections (byte strings, then close).
class ScriptedServer {
 public:
  explicit ScriptedServer(std::vector<std::vector<std::uint8_t>> connections)
      : connections_(std::move(connections)) {
    listener_ = tcp::Listen("127.0.0.1", 0, port_);
    thread_ = std::thread([this] {
      for (auto& bytes : connections_) {
        tcp::Fd fd;
        for (int tries = 0; tries < 100 && !fd.valid(); ++tries) fd = tcp::Accept(listener_, 50);
        if (!fd.valid()) return;
        tcp::WriteAll(fd.get(), bytes.data(), bytes.size(), 2000);
        // Let the client read everything before the close (a close with unread data is fine
        // too, but a lingering close keeps the script deterministic).
        std::this_thread::sleep_for(50ms);
        ++served_;
      }
    });
  }
  ~ScriptedServer() { thread_.join(); }
  int port() const { return port_; }
  int served() const { return served_; }

 private:
  std::vector<std::vector<std::uint8_t>> connections_;
  tcp::Fd listener_;
  int port_ = 0;
  std::atomic<int> served_{0};
  std::thread thread_;
};

std::vector<std::uint8_t> Frame(double t) {
  VolumeGeometry g;
  g.dims = {8, 6, 4};
  Volume v = Volume::Create(g, 77);
  v.set_timestamp_s(t);
  return EncodeImage(v);
}

using testing::PutBigEndian64;
using testing::Recrc;
void Append(std::vector<std::uint8_t>& to, const std::vector<std::uint8_t>& m) {
  to.insert(to.end(), m.begin(), m.end());
}

TEST(IgtlStream, BadInputIsCountedByReasonAndTheStreamGoesOn) {
  // Connection 1: good, bad CRC, size mismatch, too many voxels, an unknown type, a
  // reference-format STATUS-like message, good, then half a message and a close.
  std::vector<std::uint8_t> c1;
  Append(c1, Frame(1.0));
  auto bad_crc = Frame(99.0);
  bad_crc[100] ^= 1;
  Append(c1, bad_crc);
  auto mismatch = Frame(99.0);
  mismatch.resize(mismatch.size() - 5);
  PutBigEndian64(mismatch, 42, mismatch.size() - kHeaderBytes);
  Recrc(mismatch);
  Append(c1, mismatch);
  auto huge = Frame(99.0);  // 60000 x 60000 x 4 announced in a 264-byte body
  for (int a = 0; a < 2; ++a) {
    huge[58 + 6 + 2 * a] = 0xEA;
    huge[58 + 7 + 2 * a] = 0x60;
  }
  Recrc(huge);
  Append(c1, huge);
  std::vector<std::uint8_t> unknown(kHeaderBytes + 10, 0);
  unknown[1] = 1;
  std::memcpy(&unknown[2], "FOOBAR", 6);
  PutBigEndian64(unknown, 42, 10);
  for (int k = 0; k < 10; ++k) unknown[kHeaderBytes + k] = static_cast<std::uint8_t>(k);
  Recrc(unknown);
  Append(c1, unknown);
  Append(c1, Frame(2.0));
  auto half = Frame(99.0);
  half.resize(half.size() / 2);
  Append(c1, half);
  // Connection 2: 58 bytes of garbage (cannot resynchronise: reconnect).
  std::vector<std::uint8_t> c2(kHeaderBytes, 0xA5);
  Append(c2, Frame(98.0));  // lost with the connection
  // Connection 3: a header announcing a body beyond max_body_bytes.
  auto oversize = Frame(97.0);
  PutBigEndian64(oversize, 42, 1ULL << 40);
  std::vector<std::uint8_t> c3 = oversize;
  // Connection 4: good.
  std::vector<std::uint8_t> c4 = Frame(3.0);

  ScriptedServer server({c1, c2, c3, c4});
  IngestOptions io = Loopback(server.port());
  io.limits.max_voxels = 1 << 20;
  io.limits.max_body_bytes = (1 << 20) + 4096;
  IngestClient ingest(io);
  ingest.Start();
  ASSERT_TRUE(WaitFor([&] { return ingest.stats().frames == 3 && server.served() == 4; }));
  const IngestStats s = ingest.stats();
  EXPECT_EQ(s.frames, 3);
  EXPECT_EQ(s.connections, 4);
  EXPECT_EQ(s.rejected_by_reason.at("bad_crc"), 1);
  EXPECT_EQ(s.rejected_by_reason.at("body_size_mismatch"), 1);
  EXPECT_EQ(s.rejected_by_reason.at("too_many_voxels"), 1);
  EXPECT_EQ(s.rejected_by_reason.at("truncated_message"), 1);
  EXPECT_EQ(s.rejected_by_reason.at("bad_header"), 1);
  EXPECT_EQ(s.rejected_by_reason.at("body_too_large"), 1);
  EXPECT_EQ(s.rejected, 6);
  EXPECT_EQ(s.skipped_by_type.at("FOOBAR"), 1);
  EXPECT_EQ(s.dropped, 0);
  for (double t : {1.0, 2.0, 3.0}) {
    auto f = ingest.NextFrame(1.0);
    ASSERT_TRUE(f);
    EXPECT_DOUBLE_EQ(f->frame.volume.timestamp_s(), t);
    EXPECT_EQ(f->frame.volume.voxels()[0], 77);
  }
  ingest.Stop();
  EXPECT_FALSE(ingest.Next());  // ended
}

TEST(IgtlStream, GivesUpAfterConfiguredConnectFailures) {
  int port = 0;
  { tcp::Fd probe = tcp::Listen("127.0.0.1", 0, port); }  // a port nobody listens on now
  IngestOptions io = Loopback(port);
  io.max_connect_failures = 2;
  IngestClient ingest(io);
  ingest.Start();
  EXPECT_FALSE(ingest.Next());
  EXPECT_EQ(ingest.stats().connect_failures, 3);
  EXPECT_TRUE(ingest.ended());
}

}  // namespace
}  // namespace echoservo::imaging::openigtlink
