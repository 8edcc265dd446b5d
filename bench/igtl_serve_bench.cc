// The detection server's cost to the tracker (deliverable "Detections out", docs/slicer.md):
// the tracker node (live::TrackerNode: Radon detector + predictor competition; no DDS, no RUN
// directory) processes the same simulated volumes (live::SimScene, the demo's water tank,
// rendered once before timing) paced at --rate-hz, in alternating phases in one process:
//   baseline  no server
//   serve     an imaging::openigtlink::DetectionServer with 3 clients connected, 2 reading
//             every message and 1 connected but never reading; each processed volume is
//             published (the call the tracker makes with --igtl-serve)
// Rounds alternate baseline/serve in ABBA order (--rounds each), so a change of load on the
// host hits both. The readers are threads of this process at normal priority (standing in for
// Slicer, another process on the same host); the server thread runs at its default nice 10.
// Per volume: the tracker's time (Process + Publish, ms) and its latency (the volume's slot
// time → Process + Publish done, ms: what the servo's latency inherits); for the serve phases
// also Publish → each reading client's receive of the volume's TRANSFORM (ms, wall clock of
// one host) and the server's counts (drops and cut-off of the stalled client).
// Prints JSON. Options: --volumes N (40) --rounds R (2) --rate-hz F (25) --with-images
// (IMAGE messages too, ~5 MB each: the stalled client's queue fills and it is cut off).
// Bad options exit 2 naming the option. Binary: build/bin/echoservo_igtl_serve_bench.
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "imaging/igtl/detection_server.h"
#include "imaging/igtl/image_message.h"
#include "imaging/igtl/tcp.h"
#include "live/sim_scene.h"
#include "live/tracker_node.h"

namespace igtl = echoservo::imaging::openigtlink;
namespace live = echoservo::live;
using Clock = std::chrono::steady_clock;

namespace {

struct Options {
  int volumes = 40;
  int rounds = 2;
  double rate_hz = 25.0;
  bool with_images = false;
};

[[noreturn]] void Usage(const std::string& why) {
  std::fprintf(stderr,
               "echoservo_igtl_serve_bench: %s\nusage: echoservo_igtl_serve_bench [--volumes N] "
               "[--rounds R] [--rate-hz F] [--with-images]\n",
               why.c_str());
  std::exit(2);
}

Options Parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> std::string {
      if (i + 1 >= argc) Usage(std::string(name) + " needs a value");
      return argv[++i];
    };
    try {
      if (a == "--volumes") {
        o.volumes = std::stoi(value("--volumes"));
        if (o.volumes < 5 || o.volumes > 1000) Usage("--volumes must be in [5, 1000]");
      } else if (a == "--rounds") {
        o.rounds = std::stoi(value("--rounds"));
        if (o.rounds < 1 || o.rounds > 20) Usage("--rounds must be in [1, 20]");
      } else if (a == "--rate-hz") {
        o.rate_hz = std::stod(value("--rate-hz"));
        if (!(o.rate_hz > 0.0 && o.rate_hz <= 100.0)) Usage("--rate-hz must be in (0, 100]");
      } else if (a == "--with-images") {
        o.with_images = true;
      } else {
        Usage("unknown option " + a);
      }
    } catch (const std::logic_error&) {
      Usage("bad value for " + a);
    }
  }
  return o;
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(pos);
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

nlohmann::json Summary(const std::vector<double>& v) {
  return {{"p50", Quantile(v, 0.5)},
          {"p99", Quantile(v, 0.99)},
          {"max", v.empty() ? 0.0 : *std::max_element(v.begin(), v.end())},
          {"count", v.size()}};
}

// A reading client on a plain socket (header parsed by ParseHeader, bodies skipped): the
// receive time of each TRANSFORM, keyed by its raw timestamp.
class ReadingClient {
 public:
  explicit ReadingClient(int port) {
    std::string error;
    fd_ = igtl::tcp::Connect("127.0.0.1", port, 2000, error);
    if (!fd_.valid()) throw std::runtime_error("connect: " + error);
    thread_ = std::thread([this] { Loop(); });
  }
  ~ReadingClient() {
    stop_ = true;
    ::shutdown(fd_.get(), SHUT_RDWR);
    if (thread_.joinable()) thread_.join();
  }
  std::map<std::uint64_t, double> received() {
    std::lock_guard lock(mutex_);
    return received_;
  }

 private:
  void Loop() {
    std::vector<std::uint8_t> header(igtl::kHeaderBytes), body;
    igtl::DecodeLimits limits;
    while (!stop_) {
      std::size_t got = 0;
      if (igtl::tcp::ReadExact(fd_.get(), header.data(), header.size(), 200, got) !=
          igtl::tcp::IoResult::kOk) {
        if (got == 0 && !stop_) continue;
        return;
      }
      igtl::MessageHeader h;
      try {
        h = igtl::ParseHeader(header, limits);
      } catch (const igtl::MessageError&) {
        return;  // counted by the server's stats as nothing; the bench reports fewer receipts
      }
      body.resize(h.body_size);
      if (igtl::tcp::ReadExact(fd_.get(), body.data(), body.size(), 2000, got) !=
          igtl::tcp::IoResult::kOk) {
        return;
      }
      if (h.type == "TRANSFORM") {
        const double now = igtl::WallClockSeconds();
        std::lock_guard lock(mutex_);
        received_[h.timestamp] = now;
      }
    }
  }

  igtl::tcp::Fd fd_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  std::mutex mutex_;
  std::map<std::uint64_t, double> received_;
};

struct Phase {
  std::vector<double> tracker_ms, latency_ms, client_ms, publish_ms;
  std::uint64_t found = 0;
  nlohmann::json server = nullptr;
};

Phase RunPhase(const Options& o, const std::vector<echoservo::imaging::Volume>& volumes,
               const std::vector<double>& acquired_s, bool serve, double epoch_unix_s) {
  Phase out;
  std::unique_ptr<igtl::DetectionServer> server;
  std::unique_ptr<ReadingClient> a, b;
  igtl::tcp::Fd stalled;
  if (serve) {
    igtl::DetectionServerOptions so;
    so.send_volumes = o.with_images;
    server = std::make_unique<igtl::DetectionServer>(so);
    server->Start();
    a = std::make_unique<ReadingClient>(server->port());
    b = std::make_unique<ReadingClient>(server->port());
    std::string error;
    stalled = igtl::tcp::Connect("127.0.0.1", server->port(), 2000, error);
    if (!stalled.valid()) throw std::runtime_error("connect: " + error);
    const auto until = Clock::now() + std::chrono::seconds(2);
    while (server->stats().clients_now < 3 && Clock::now() < until) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
  live::TrackerNodeOptions to;
  live::TrackerNode node(to, nullptr, nullptr);
  const auto start = Clock::now();
  std::map<std::uint64_t, double> published_unix;  // raw stamp → Publish wall time
  for (std::size_t i = 0; i < volumes.size(); ++i) {
    const auto slot = start + std::chrono::duration_cast<Clock::duration>(
                                  std::chrono::duration<double>(i / o.rate_hz));
    std::this_thread::sleep_until(slot);
    const auto t0 = Clock::now();
    const double t = acquired_s[i];
    const live::TrackedVolume r = node.Process(volumes[i], t, t, [t] { return t; });
    if (server) {
      igtl::DetectionSample s;
      s.acquired_unix_s = epoch_unix_s + t;
      s.found = r.error.empty() && r.detection.found;
      s.tip_mm = r.detection.tip_mm;
      s.axis = r.detection.axis.direction;
      if (r.detection.target_found) s.target_mm = r.detection.target_mm;
      published_unix[igtl::SecondsToIgtlTimestamp(s.acquired_unix_s)] = igtl::WallClockSeconds();
      const auto p0 = Clock::now();
      server->Publish(s, &volumes[i]);
      out.publish_ms.push_back(
          std::chrono::duration<double, std::milli>(Clock::now() - p0).count());
    }
    const auto t1 = Clock::now();
    out.found += r.detection.found;
    out.tracker_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    out.latency_ms.push_back(std::chrono::duration<double, std::milli>(t1 - slot).count());
  }
  if (server) {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the last messages
    for (ReadingClient* c : {a.get(), b.get()}) {
      for (const auto& [stamp, recv_unix] : c->received()) {
        const auto it = published_unix.find(stamp);
        if (it != published_unix.end()) out.client_ms.push_back(1e3 * (recv_unix - it->second));
      }
    }
    const igtl::DetectionServerStats s = server->stats();
    std::uint64_t stalled_dropped = 0, readers_dropped = 0;
    std::string stalled_end = "connected";
    for (const auto& c : s.clients) {
      if (c.id == 3) {
        stalled_dropped = c.messages_dropped;
        if (!c.connected) stalled_end = c.end;
      } else {
        readers_dropped += c.messages_dropped;
      }
    }
    out.server = {{"samples_published", s.samples_published},
                  {"samples_dropped", s.samples_dropped},
                  {"sent_transform", s.sent_transform},
                  {"sent_image", s.sent_image},
                  {"messages_dropped_stalled_client", stalled_dropped},
                  {"messages_dropped_reading_clients", readers_dropped},
                  {"stalled_client", stalled_end},
                  {"transforms_received_by_readers", out.client_ms.size()},
                  {"send_latency_ms_p99", s.send_latency_ms_p99},
                  {"volume_slots_allocated", s.volume_slots_allocated}};
    a.reset();
    b.reset();
    server->Stop();
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = Parse(argc, argv);
  // The demo's scene; volumes rendered once, before any timing.
  live::SimScene scene({o.rate_hz, 60.0, 10.0, 8.0, 1});
  std::vector<echoservo::imaging::Volume> volumes;
  std::vector<double> acquired;
  for (int i = 0; i < o.volumes; ++i) {
    const double t = i / o.rate_hz;
    volumes.push_back(scene.Render(t).volume);
    acquired.push_back(t);
  }
  const double epoch = igtl::WallClockSeconds();
  Phase base, serve;
  auto append = [](Phase& into, const Phase& p) {
    into.tracker_ms.insert(into.tracker_ms.end(), p.tracker_ms.begin(), p.tracker_ms.end());
    into.latency_ms.insert(into.latency_ms.end(), p.latency_ms.begin(), p.latency_ms.end());
    into.client_ms.insert(into.client_ms.end(), p.client_ms.begin(), p.client_ms.end());
    into.publish_ms.insert(into.publish_ms.end(), p.publish_ms.begin(), p.publish_ms.end());
    into.found += p.found;
  };
  nlohmann::json servers = nlohmann::json::array();
  for (int r = 0; r < o.rounds; ++r) {  // ABBA: base, serve, serve, base, ...
    for (const bool serving : {r % 2 == 1, r % 2 == 0}) {
      if (!serving) {
        append(base, RunPhase(o, volumes, acquired, false, epoch));
        continue;
      }
      const Phase s = RunPhase(o, volumes, acquired, true, epoch + 100.0 * (r + 1));
      append(serve, s);
      servers.push_back(s.server);
    }
  }
  const nlohmann::json out = {
      {"volumes_per_phase", o.volumes},
      {"rounds", o.rounds},
      {"rate_hz", o.rate_hz},
      {"with_images", o.with_images},
      {"dims", {volumes[0].dims().x(), volumes[0].dims().y(), volumes[0].dims().z()}},
      {"baseline",
       {{"tracker_ms", Summary(base.tracker_ms)},
        {"latency_ms", Summary(base.latency_ms)},
        {"found", base.found}}},
      {"serve_3_clients_1_stalled",
       {{"tracker_ms", Summary(serve.tracker_ms)},
        {"latency_ms", Summary(serve.latency_ms)},
        {"found", serve.found},
        {"publish_ms", Summary(serve.publish_ms)},
        {"publish_to_client_ms", Summary(serve.client_ms)},
        {"server_per_round", servers}}},
      {"ratio_tracker_p50", Quantile(serve.tracker_ms, 0.5) / Quantile(base.tracker_ms, 0.5)},
      {"ratio_latency_p99", Quantile(serve.latency_ms, 0.99) / Quantile(base.latency_ms, 0.99)}};
  std::printf("%s\n", out.dump(2).c_str());
  return 0;
}
