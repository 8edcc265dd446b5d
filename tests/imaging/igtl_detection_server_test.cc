// The detection server (imaging/igtl/detection_server.h) over loopback, with clients built
// from libOpenIGTLink's own igtl::ClientSocket and message classes (they share no code with
// our encoders): TRANSFORM/POINT/STATUS/IMAGE arrive with the published values in RAS and the
// acquisition timestamps, the catheter tip lands on the same voxel of the received IMAGE as
// in ours; three clients of which one never reads: the two others get every message, the
// stalled one's drops are counted, it is cut off, and Publish() never waits for it; clients
// that send messages, garbage, or vanish are handled while another keeps receiving; the
// --igtl-serve flags of `echoservo track` (errors, and a run serving a client).
#include <gtest/gtest.h>
#include <igtlClientSocket.h>
#include <igtlImageMessage.h>
#include <igtlMessageHeader.h>
#include <igtlPointMessage.h>
#include <igtlStatusMessage.h>
#include <igtlTransformMessage.h>
#include <sys/socket.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "imaging/igtl/detection_server.h"
#include "imaging/igtl/image_server.h"
#include "imaging/igtl/phantom_source.h"
#include "imaging/igtl/tcp.h"
#include "imaging/igtl/tracking_messages.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo::imaging::openigtlink {
namespace detection_server_test {
namespace {

using namespace std::chrono_literals;

// One message as libOpenIGTLink unpacked it.
struct Received {
  std::string type, device;
  double timestamp_s = 0.0;
  igtl::MessageBase::Pointer message;
};

// A reading client: igtl::ClientSocket + igtl::MessageHeader, bodies unpacked with their CRC
// checked by libOpenIGTLink, on its own thread until `want` messages or the socket ends.
class LibIgtlReader {
 public:
  LibIgtlReader(int port, std::size_t want) : socket_(igtl::ClientSocket::New()) {
    connected_ = socket_->ConnectToServer("127.0.0.1", port) == 0;
    socket_->SetReceiveTimeout(3000);
    if (connected_) thread_ = std::thread([this, want] { Loop(want); });
  }
  ~LibIgtlReader() {
    if (thread_.joinable()) thread_.join();
    socket_->CloseSocket();
  }
  bool connected() const { return connected_; }
  void Join() {
    if (thread_.joinable()) thread_.join();
  }
  const std::vector<Received>& messages() const { return messages_; }
  int crc_failures() const { return crc_failures_; }

 private:
  void Loop(std::size_t want) {
    while (messages_.size() < want) {
      igtl::MessageHeader::Pointer header = igtl::MessageHeader::New();
      header->InitPack();
      if (socket_->Receive(header->GetPackPointer(), header->GetPackSize()) !=
          header->GetPackSize()) {
        return;
      }
      header->Unpack();
      const std::string type = header->GetDeviceType();
      igtl::MessageBase::Pointer body;
      if (type == "TRANSFORM") body = igtl::TransformMessage::New().GetPointer();
      if (type == "POINT") body = igtl::PointMessage::New().GetPointer();
      if (type == "STATUS") body = igtl::StatusMessage::New().GetPointer();
      if (type == "IMAGE") body = igtl::ImageMessage::New().GetPointer();
      if (!body) return;  // a type the server never sends
      body->SetMessageHeader(header);
      body->AllocatePack();
      if (socket_->Receive(body->GetPackBodyPointer(), body->GetPackBodySize()) !=
          body->GetPackBodySize()) {
        return;
      }
      if (!(body->Unpack(1) & igtl::MessageHeader::UNPACK_BODY)) {
        ++crc_failures_;
        return;
      }
      unsigned int sec = 0, frac = 0;
      header->GetTimeStamp(&sec, &frac);
      messages_.push_back(
          {type, header->GetDeviceName(), sec + static_cast<double>(frac) / 4294967296.0, body});
    }
  }

  igtl::ClientSocket::Pointer socket_;
  bool connected_ = false;
  std::thread thread_;
  std::vector<Received> messages_;
  int crc_failures_ = 0;
};

template <typename F>
bool WaitUntil(F done, std::chrono::milliseconds limit = 2000ms) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(2ms);
  }
  return done();
}

// A small volume in LPS with an oblique direction, so that a frame error shows.
Volume TestVolume(std::uint8_t seed) {
  VolumeGeometry g;
  g.dims = Eigen::Vector3i(20, 16, 12);
  g.spacing_mm = Eigen::Vector3d(0.5, 0.6, 0.7);
  g.origin_mm = Eigen::Vector3d(-10, 5, 30);
  g.direction = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0, 0, 1)).toRotationMatrix();
  Volume v = Volume::Create(g);
  auto vox = v.voxels();
  for (std::size_t i = 0; i < vox.size(); ++i) vox[i] = static_cast<std::uint8_t>(i * 7 + seed);
  v.set_timestamp_s(3.0);  // a pipeline time: must not reach the wire
  return v;
}

constexpr double kT0 = 1790000000.25;  // acquisition, s since the Unix epoch
// 32.32 timestamps are exact to 2.3e-10 s; the double holding ~1.8e9 s to 2.4e-7 s.
constexpr double kStampTol = 1e-6;

TEST(IgtlDetectionServer, LibIgtlClientReceivesDetectionsInTheImageFrame) {
  DetectionServerOptions o;
  o.send_volumes = true;
  DetectionServer server(o);
  server.Start();
  // Expected: IMAGE TRANSFORM POINT | IMAGE STATUS(lost) | IMAGE TRANSFORM POINT STATUS(ok).
  LibIgtlReader reader(server.port(), 9);
  ASSERT_TRUE(reader.connected());
  ASSERT_TRUE(WaitUntil([&] { return server.stats().clients_now == 1; }));

  const Volume volume = TestVolume(1);
  // The tip at a voxel centre (continuous index (7, 5, 4)), the axis oblique.
  const Eigen::Vector3d tip_lps = volume.IndexToPhysical(Eigen::Vector3d(7, 5, 4));
  const Eigen::Vector3d axis_lps = Eigen::Vector3d(0.2, -0.3, 1.0).normalized();
  const Eigen::Vector3d target_lps = tip_lps + 6.0 * axis_lps;
  DetectionSample found;
  found.acquired_unix_s = kT0;
  found.found = true;
  found.tip_mm = tip_lps;
  found.axis = axis_lps;
  found.target_mm = target_lps;
  found.confidence = 0.9;
  server.Publish(found, &volume);
  DetectionSample lost;
  lost.acquired_unix_s = kT0 + 0.04;
  server.Publish(lost, &volume);
  DetectionSample again = found;
  again.acquired_unix_s = kT0 + 0.08;
  again.target_mm.reset();
  server.Publish(again, &volume);
  reader.Join();

  const auto& m = reader.messages();
  ASSERT_EQ(m.size(), 9u);
  EXPECT_EQ(reader.crc_failures(), 0);
  const std::vector<std::string> types = {"IMAGE", "TRANSFORM", "POINT", "IMAGE", "STATUS",
                                          "IMAGE", "TRANSFORM", "POINT", "STATUS"};
  const std::vector<double> stamps = {kT0,        kT0,        kT0,        kT0 + 0.04, kT0 + 0.04,
                                      kT0 + 0.08, kT0 + 0.08, kT0 + 0.08, kT0 + 0.08};
  for (std::size_t i = 0; i < m.size(); ++i) {
    EXPECT_EQ(m[i].type, types[i]) << i;
    EXPECT_NEAR(m[i].timestamp_s, stamps[i], kStampTol) << i;
  }
  EXPECT_EQ(m[0].device, "Image");
  EXPECT_EQ(m[1].device, "CatheterToImage");
  EXPECT_EQ(m[2].device, "Detections");
  EXPECT_EQ(m[4].device, "CatheterToImage");

  const Eigen::Vector3d flip(-1, -1, 1);  // LPS → RAS
  const Eigen::Vector3d tip_ras = flip.cwiseProduct(tip_lps);
  // TRANSFORM: origin at the tip, z along the axis, in RAS.
  auto* tm = dynamic_cast<igtl::TransformMessage*>(m[1].message.GetPointer());
  ASSERT_NE(tm, nullptr);
  igtl::Matrix4x4 t;
  tm->GetMatrix(t);
  for (int r = 0; r < 3; ++r) {
    EXPECT_NEAR(t[r][3], tip_ras[r], 1e-4);  // float32 of ~40 mm
    EXPECT_NEAR(t[r][2], flip[r] * axis_lps[r], 1e-6);
  }
  // POINT: the tip and the target.
  auto* pm = dynamic_cast<igtl::PointMessage*>(m[2].message.GetPointer());
  ASSERT_NE(pm, nullptr);
  ASSERT_EQ(pm->GetNumberOfPointElement(), 2);
  const Eigen::Vector3d expected[2] = {tip_ras, flip.cwiseProduct(target_lps)};
  const char* names[2] = {"CatheterTip", "Target"};
  for (int i = 0; i < 2; ++i) {
    igtl::PointElement::Pointer e;
    pm->GetPointElement(i, e);
    EXPECT_STREQ(e->GetName(), names[i]);
    float p[3];
    e->GetPosition(p);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(p[k], expected[i][k], 1e-4);
  }
  auto* pm2 = dynamic_cast<igtl::PointMessage*>(m[7].message.GetPointer());
  ASSERT_NE(pm2, nullptr);
  EXPECT_EQ(pm2->GetNumberOfPointElement(), 1);  // no target the third time
  // STATUS: not found, then found again.
  auto* s_lost = dynamic_cast<igtl::StatusMessage*>(m[4].message.GetPointer());
  auto* s_ok = dynamic_cast<igtl::StatusMessage*>(m[8].message.GetPointer());
  ASSERT_TRUE(s_lost && s_ok);
  EXPECT_EQ(s_lost->GetCode(), static_cast<int>(StatusCode::kNotFound));
  EXPECT_EQ(s_ok->GetCode(), static_cast<int>(StatusCode::kOk));

  // IMAGE: our voxels, and the tip falls on voxel (7, 5, 4) of the image as libOpenIGTLink
  // places it (origin = the volume's centre, normals × spacing, RAS): the overlay in Slicer.
  auto* im = dynamic_cast<igtl::ImageMessage*>(m[0].message.GetPointer());
  ASSERT_NE(im, nullptr);
  int dims[3];
  im->GetDimensions(dims);
  ASSERT_EQ(Eigen::Vector3i(dims[0], dims[1], dims[2]), volume.dims());
  EXPECT_EQ(std::memcmp(im->GetScalarPointer(), volume.voxels().data(), volume.voxel_count()), 0);
  EXPECT_EQ(im->GetCoordinateSystem(), igtl::ImageMessage::COORDINATE_RAS);
  igtl::Matrix4x4 im_m;
  im->GetMatrix(im_m);
  float spacing[3];
  im->GetSpacing(spacing);
  Eigen::Vector3d tip_from_image = Eigen::Vector3d::Zero();
  const Eigen::Vector3d index(7, 5, 4);
  for (int r = 0; r < 3; ++r) {
    tip_from_image[r] = im_m[r][3];
    for (int c = 0; c < 3; ++c) {
      tip_from_image[r] += im_m[r][c] * spacing[c] * (index[c] - (dims[c] - 1) / 2.0);
    }
  }
  EXPECT_LT((tip_from_image - tip_ras).norm(), 1e-3);  // float32 geometry, ~40 mm

  // The server counts a message once send() returned: possibly just after the client has it.
  EXPECT_TRUE(WaitUntil([&] { return server.stats().sent_status == 2; }));
  const DetectionServerStats st = server.stats();
  EXPECT_EQ(st.samples_published, 3u);
  EXPECT_EQ(st.samples_encoded, 3u);
  EXPECT_EQ(st.sent_image, 3u);
  EXPECT_EQ(st.sent_transform, 2u);
  EXPECT_EQ(st.sent_points, 2u);
  EXPECT_EQ(st.sent_status, 2u);
  EXPECT_EQ(st.messages_dropped, 0u);
  ASSERT_EQ(st.clients.size(), 1u);
  EXPECT_EQ(st.clients[0].messages_sent, 9u);
  // Three volumes through at most pending_samples + 1 slots: reused, not one per volume.
  EXPECT_LE(st.volume_slots_allocated, 3u);
}

TEST(IgtlDetectionServer, StalledClientDropsAndIsCutOffWhileOthersGetEverything) {
  DetectionServerOptions o;
  o.send_volumes = true;
  o.client_queue_bytes = 2u << 20;  // 2 MiB: ~60 volumes of 32 KiB
  o.client_queue_messages = 1024;
  o.socket_send_buffer_bytes = 64 << 10;
  o.stall_timeout_ms = 500;
  o.pending_samples = 256;  // every sample reaches the server thread, even on a loaded host
  o.thread_nice = 0;        // the same: this test is about the queues, not the priority
  DetectionServer server(o);
  server.Start();
  constexpr int kSamples = 200;  // 200 × (32 KiB IMAGE + TRANSFORM + POINT) ≈ 6.5 MB
  LibIgtlReader a(server.port(), 3 * kSamples), b(server.port(), 3 * kSamples);
  // The stalled client: connected, never reads.
  std::string error;
  tcp::Fd stalled = tcp::Connect("127.0.0.1", server.port(), 2000, error);
  ASSERT_TRUE(stalled.valid()) << error;
  int small = 4096;  // a small receive window, so the server's queue for it fills
  ::setsockopt(stalled.get(), SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  ASSERT_TRUE(a.connected() && b.connected());
  ASSERT_TRUE(WaitUntil([&] { return server.stats().clients_now == 3; }));

  VolumeGeometry g;
  g.dims = Eigen::Vector3i(32, 32, 32);
  Volume volume = Volume::Create(g, 9);
  double max_publish_ms = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    DetectionSample s;
    s.acquired_unix_s = kT0 + 0.002 * i;
    s.found = true;
    s.tip_mm = Eigen::Vector3d(1, 2, 3 + 0.01 * i);
    const auto t0 = std::chrono::steady_clock::now();
    server.Publish(s, &volume);
    max_publish_ms = std::max(
        max_publish_ms,
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    std::this_thread::sleep_for(2ms);
  }
  a.Join();
  b.Join();
  // Blocking on the stalled socket would take the stall timeout (500 ms); a copy of 32 KiB
  // and a queue push take microseconds (100 ms: a loaded host's scheduling).
  EXPECT_LT(max_publish_ms, 100.0);
  for (const LibIgtlReader* r : {&a, &b}) {
    ASSERT_EQ(r->messages().size(), 3u * kSamples);
    for (int i = 0; i < kSamples; ++i) {  // every message, in order
      EXPECT_EQ(r->messages()[3 * i].type, "IMAGE");
      EXPECT_NEAR(r->messages()[3 * i + 1].timestamp_s, kT0 + 0.002 * i, kStampTol);
    }
  }
  // The server counts the stall when it closes the client and the clients left once it has
  // removed it, a moment later (two updates): wait for both.
  ASSERT_TRUE(WaitUntil(
      [&] {
        const DetectionServerStats now = server.stats();
        return now.clients_stalled == 1 && now.clients_now == 2;
      },
      1500ms));
  const DetectionServerStats st = server.stats();
  EXPECT_EQ(st.samples_dropped, 0u);
  EXPECT_EQ(st.clients_now, 2);
  ASSERT_EQ(st.clients.size(), 3u);
  std::uint64_t stalled_drops = 0, others_drops = 0;
  for (const auto& c : st.clients) {
    if (c.end == "stalled") {
      stalled_drops += c.messages_dropped;
      // What it did take is what its socket buffers held, far less than the 6.5 MB sent.
      EXPECT_LT(c.bytes_sent, 2'000'000u);
    } else {
      others_drops += c.messages_dropped;
      EXPECT_TRUE(c.connected);
    }
  }
  EXPECT_GT(stalled_drops, 0u);
  EXPECT_EQ(others_drops, 0u);
  EXPECT_EQ(st.messages_dropped, stalled_drops);
}

TEST(IgtlDetectionServer, ClientsThatSendMessagesGarbageOrVanishAreHandled) {
  DetectionServer server(DetectionServerOptions{});
  server.Start();
  LibIgtlReader reader(server.port(), 4);  // 2 samples × (TRANSFORM, POINT)
  ASSERT_TRUE(reader.connected());
  std::string error;
  // A Slicer-like client: sends a STATUS and a GET_TRANS built by libOpenIGTLink.
  tcp::Fd talker = tcp::Connect("127.0.0.1", server.port(), 2000, error);
  ASSERT_TRUE(talker.valid()) << error;
  igtl::StatusMessage::Pointer status = igtl::StatusMessage::New();
  status->SetDeviceName("Slicer");
  status->SetCode(igtl::StatusMessage::STATUS_OK);
  status->SetStatusString("hello");
  status->Pack();
  igtl::GetTransformMessage::Pointer get = igtl::GetTransformMessage::New();
  get->SetDeviceName("CatheterToImage");
  get->Pack();
  ASSERT_EQ(tcp::WriteAll(talker.get(), status->GetPackPointer(), status->GetPackSize(), 1000),
            tcp::IoResult::kOk);
  ASSERT_EQ(tcp::WriteAll(talker.get(), get->GetPackPointer(), get->GetPackSize(), 1000),
            tcp::IoResult::kOk);
  // A client that sends garbage, and one that connects and leaves.
  tcp::Fd garbage = tcp::Connect("127.0.0.1", server.port(), 2000, error);
  ASSERT_TRUE(garbage.valid()) << error;
  std::vector<std::uint8_t> junk(100, 0xFF);
  ASSERT_EQ(tcp::WriteAll(garbage.get(), junk.data(), junk.size(), 1000), tcp::IoResult::kOk);
  {
    tcp::Fd leaver = tcp::Connect("127.0.0.1", server.port(), 2000, error);
    ASSERT_TRUE(leaver.valid()) << error;
    ASSERT_TRUE(WaitUntil([&] { return server.stats().clients_accepted == 4; }));
  }
  ASSERT_TRUE(WaitUntil([&] {
    const auto s = server.stats();
    return s.client_messages_received == 2 && s.client_messages_rejected == 1 &&
           s.clients_disconnected == 2;
  })) << server.stats().client_messages_received
      << " received, " << server.stats().client_messages_rejected << " rejected, "
      << server.stats().clients_disconnected << " disconnected";

  // The server goes on: the reader and the talker still get samples. One sample cannot be
  // encoded (NaN): counted, skipped.
  DetectionSample s;
  s.acquired_unix_s = kT0;
  s.found = true;
  s.tip_mm = Eigen::Vector3d(1, 2, 3);
  server.Publish(s);
  DetectionSample bad = s;
  bad.tip_mm.x() = std::numeric_limits<double>::quiet_NaN();
  server.Publish(bad);
  s.acquired_unix_s = kT0 + 0.1;
  server.Publish(s);
  reader.Join();
  ASSERT_EQ(reader.messages().size(), 4u);
  EXPECT_NEAR(reader.messages()[3].timestamp_s, kT0 + 0.1, kStampTol);
  const DetectionServerStats st = server.stats();
  EXPECT_EQ(st.encode_errors, 1u);
  EXPECT_NE(st.last_encode_error.find("finite"), std::string::npos) << st.last_encode_error;
  EXPECT_EQ(st.clients_now, 2);
  std::map<std::string, int> ends;
  for (const auto& c : st.clients) ++ends[c.connected ? "connected" : c.end];
  EXPECT_EQ(ends["connected"], 2);
  EXPECT_EQ(ends["bad_header"], 1);
  EXPECT_EQ(ends["closed"], 1);
}

TEST(IgtlDetectionServer, RejectsBadOptions) {
  DetectionServerOptions o;
  o.transform_name = "ANameThatIsLongerThan20";
  EXPECT_THROW(DetectionServer{o}, std::invalid_argument);
  o = {};
  o.client_queue_messages = 0;
  EXPECT_THROW(DetectionServer{o}, std::invalid_argument);
  o = {};
  o.port = 70000;
  EXPECT_THROW(DetectionServer{o}, std::invalid_argument);
}

// The flags of `track` and `demo` (apps/commands/igtl_serve_flags.h): mistakes are errors
// naming the flag, before the run starts (a port in use: before any DDS participant or scan).
TEST(IgtlDetectionServer, CliRejectsBadIgtlFlagsBeforeTheRun) {
  ECHOSERVO_REQUIRES_CLI();
  using ::echoservo::testing::RunCli;
  const auto no_port = RunCli("demo --duration 1 --igtl-volumes");
  EXPECT_EQ(no_port.rc, 1);
  EXPECT_NE(no_port.err.find("--igtl-volumes: needs --igtl-serve PORT"), std::string::npos)
      << no_port.err;
  // A port another server holds.
  DetectionServer holder(DetectionServerOptions{});
  holder.Start();
  const auto busy =
      RunCli("track --sim --duration 1 --igtl-serve " + std::to_string(holder.port()));
  EXPECT_EQ(busy.rc, 1);
  EXPECT_NE(busy.err.find("--igtl-serve " + std::to_string(holder.port())), std::string::npos)
      << busy.err;
  EXPECT_EQ(holder.stats().clients_accepted, 0u);  // nobody connected to the holder
}

// A port nothing listens on now (bound, then released).
int FreePort() {
  int port = 0;
  tcp::Fd probe = tcp::Listen("127.0.0.1", 0, port);
  return port;
}

// `echoservo track --connect … --igtl-serve PORT` end to end: a scanner (ImageServer, wall-clock
// stamps) feeds the tracker process; a libOpenIGTLink client of the tracker's detection server
// gets the detections, stamped on the Unix clock within the run and in order, and `--json`'s
// igtl_serve counts what was published.
TEST(IgtlDetectionServer, TrackConnectServesDetectionsToALibIgtlClient) {
  ECHOSERVO_REQUIRES_CLI();
  ECHOSERVO_RELEASE_SUITE_ONLY("runs the tracker process for 1.5 s; the server is tested above");
  PhantomOptions po;
  po.dims = {80, 60, 60};
  po.rate_hz = 20.0;
  PhantomSource source(po);
  ImageServerOptions so;
  so.timestamps = ImageServerOptions::Timestamps::kSendTime;
  so.max_duration_s = 5.0;
  ImageServer scanner(source, so);
  scanner.Start();
  const int serve_port = FreePort();
  const double start_unix = WallClockSeconds();
  ::echoservo::testing::RunResult track;
  std::thread run([&] {
    track = ::echoservo::testing::RunCli(
        "track --connect 127.0.0.1:" + std::to_string(scanner.port()) +
        " --duration 1.5 --loopback --dds-domain 73 --json --igtl-serve " +
        std::to_string(serve_port));
  });
  // Wait (quietly: a probe of our own) until the tracker process listens.
  bool listening = false;
  for (int attempt = 0; attempt < 150 && !listening; ++attempt) {
    std::string error;
    listening = tcp::Connect("127.0.0.1", serve_port, 1000, error).valid();
    if (!listening) std::this_thread::sleep_for(20ms);
  }
  ASSERT_TRUE(listening);
  auto reader = std::make_unique<LibIgtlReader>(serve_port, 6);
  ASSERT_TRUE(reader->connected());
  reader->Join();
  run.join();
  scanner.Stop();
  const double end_unix = WallClockSeconds();
  ASSERT_EQ(track.rc, 0) << track.err;
  ASSERT_GE(reader->messages().size(), 2u) << track.err;
  double last = 0.0;
  for (const Received& m : reader->messages()) {
    EXPECT_TRUE(m.type == "TRANSFORM" || m.type == "POINT" || m.type == "STATUS") << m.type;
    EXPECT_GE(m.timestamp_s, start_unix);  // the scanner's send time: within the run
    EXPECT_LE(m.timestamp_s, end_unix);
    EXPECT_GE(m.timestamp_s, last);  // a volume's messages share its stamp
    last = m.timestamp_s;
  }
  const auto j = nlohmann::json::parse(track.out, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << track.out;
  EXPECT_EQ(j["igtl_serve"]["samples_published"], j["volumes"]);
  EXPECT_GE(j["igtl_serve"]["clients_accepted"].get<int>(), 1);
  EXPECT_EQ(j["igtl_serve"]["encode_errors"].get<int>(), 0);
}

}  // namespace
}  // namespace detection_server_test
}  // namespace echoservo::imaging::openigtlink
