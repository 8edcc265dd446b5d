// DDS link latency: one-way latency of the target-estimate topic (publication stamp just
// before Publish → the subscriber's callback, same host clock) at a fixed rate, p50/p90/
// p99/max, with the samples lost (best effort). Runs the publisher in a second process
// (this binary re-executed with --publisher) over the loopback-only UDP transport and over
// Fast DDS's default transports (shared memory on one host), and in a thread of this
// process (intra-process delivery is off in link::Participant: a second participant of the
// same process, over the same transports), for reference.
// Binary: build/bin/echoservo_dds_bench [--samples N] [--rate HZ] [--secure DIR] [--json].
// With --secure DIR (`echoservo security init DIR`), each run is repeated with DDS-Security
// (the publisher as DIR's "tracker", the subscriber as its "servo": authenticated,
// access-controlled, encrypted), right after its non-secure baseline in the same session.
// Across two hosts (or network namespaces): run `--subscriber` on one and `--publisher`
// on the other, each with `--domain D --transport default` and, where multicast does not
// pass, `--peer IP` (the other host) and `--interface IP` (this host's address); `--no-shm`
// keeps two network namespaces of one host on UDP. The subscriber prints the figures
// (across hosts the one-way latency includes the clocks' offset).
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "link/clock.h"
#include "link/dds_link.h"
#include "link/security.h"

extern char** environ;

namespace dl = echoservo::link;

namespace {

struct Args {
  int samples = 5000;
  double rate_hz = 1000.0;
  bool json = false;
  bool publisher = false;   // the child role, or one host's side
  bool subscriber = false;  // the other host's side
  int domain = 0;
  bool loopback = true;
  std::vector<std::string> peers;
  std::vector<std::string> interfaces;
  bool shared_memory = true;
  std::string secure_dir;   // --secure DIR
  bool use_secure = false;  // this run (or this child) with DDS-Security
};

Args Parse(int argc, char** argv) {
  Args a;
  a.domain = 200 + static_cast<int>(getpid() % 30);
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto value = [&] { return i + 1 < argc ? argv[++i] : "0"; };
    if (arg == "--samples")
      a.samples = std::atoi(value());
    else if (arg == "--rate")
      a.rate_hz = std::atof(value());
    else if (arg == "--json")
      a.json = true;
    else if (arg == "--publisher")
      a.publisher = true;
    else if (arg == "--domain")
      a.domain = std::atoi(value());
    else if (arg == "--subscriber")
      a.subscriber = true;
    else if (arg == "--transport")
      a.loopback = std::string(value()) == "loopback";
    else if (arg == "--peer")
      a.peers.push_back(value());
    else if (arg == "--interface")
      a.interfaces.push_back(value());
    else if (arg == "--no-shm")
      a.shared_memory = false;
    else if (arg == "--secure") {
      a.secure_dir = value();
      a.use_secure = true;
    }
  }
  return a;
}

// `role`: the participant's identity in --secure DIR (publisher: tracker, subscriber: servo).
dl::ParticipantOptions Options(const Args& a, const char* name, const char* role) {
  dl::ParticipantOptions o;
  if (a.use_secure) o.properties = dl::SecurityProperties(dl::CheckSecurityDir(a.secure_dir, role));
  o.domain_id = a.domain;
  o.name = name;
  o.loopback_only = a.loopback;
  o.initial_peers = a.peers;
  o.interfaces = a.interfaces;
  o.shared_memory = a.shared_memory;
  return o;
}

// Publishes `samples` estimates at `rate_hz` once a subscriber matched (and 0.5 s more,
// 1 s with DDS-Security, so that the subscriber's side has matched too).
void Publish(dl::Participant& participant, int samples, double rate_hz, bool secure) {
  dl::TargetPublisher pub(participant);
  if (!pub.WaitForSubscribers(1, 30.0)) return;
  std::this_thread::sleep_for(
      std::chrono::milliseconds(secure ? 1000 : 500));  // the handshake's tail
  dl::TargetEstimateSample s;
  s.axis = Eigen::Vector3d::UnitZ();
  s.motion.cos_mm = {3.0, -0.5, 0.2, 0.1};
  s.motion.sin_mm = {0.0, 0.7, -0.1, 0.05};
  s.confidence = 0.9;
  const auto period = std::chrono::duration<double>(1.0 / rate_hz);
  auto next = std::chrono::steady_clock::now();
  for (int i = 1; i <= samples; ++i) {
    std::this_thread::sleep_until(next);
    next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
    s.sequence_number = static_cast<std::uint64_t>(i);
    s.acquisition_time_s = dl::NowS();
    s.motion.t0_s = s.acquisition_time_s;
    s.motion.valid_until_s = s.acquisition_time_s + 0.5;
    s.publication_time_s = dl::NowS();
    pub.Publish(s);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // let the last ones leave
}

struct Result {
  std::string name;
  std::size_t received = 0;
  std::uint64_t lost = 0;
  double p50_us = 0, p90_us = 0, p99_us = 0, max_us = 0;
};

double Percentile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 0.0;
  const auto i = static_cast<std::size_t>(q * static_cast<double>(sorted.size() - 1) + 0.5);
  return sorted[std::min(i, sorted.size() - 1)];
}

// Subscribes, runs the publisher (`start` → child process or thread; `join(received)`
// waits for it) and summarises the latencies.
template <class Start, class Join>
Result Measure(const std::string& name, const Args& a, Start start, Join join) {
  dl::Participant participant(Options(a, "dds_bench_subscriber", "servo"));
  std::mutex mu;
  std::vector<double> latency_us;
  latency_us.reserve(static_cast<std::size_t>(a.samples));
  dl::ValidationLimits limits;
  limits.max_target_age_s = 10.0;
  dl::TargetSubscriber sub(participant, limits,
                           [&](const dl::TargetEstimateSample& s, double received_s) {
                             std::lock_guard lock(mu);
                             latency_us.push_back(1e6 * (received_s - s.publication_time_s));
                           });
  const auto received = [&] {
    std::lock_guard lock(mu);
    return latency_us.size();
  };
  start();
  join(received);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  std::lock_guard lock(mu);
  std::sort(latency_us.begin(), latency_us.end());
  Result r;
  r.name = name;
  r.received = latency_us.size();
  r.lost = static_cast<std::uint64_t>(a.samples) - r.received;
  r.p50_us = Percentile(latency_us, 0.50);
  r.p90_us = Percentile(latency_us, 0.90);
  r.p99_us = Percentile(latency_us, 0.99);
  r.max_us = latency_us.empty() ? 0.0 : latency_us.back();
  return r;
}

Result TwoProcesses(const char* self, Args a, bool loopback) {
  a.loopback = loopback;
  pid_t pid = -1;
  const auto start = [&] {
    std::vector<std::string> args = {self,          "--publisher",
                                     "--domain",    std::to_string(a.domain),
                                     "--transport", loopback ? "loopback" : "default",
                                     "--samples",   std::to_string(a.samples),
                                     "--rate",      std::to_string(a.rate_hz)};
    if (a.use_secure) {
      args.push_back("--secure");
      args.push_back(a.secure_dir);
    }
    std::vector<char*> argv;
    for (std::string& s : args) argv.push_back(s.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid, self, nullptr, nullptr, argv.data(), environ) != 0) pid = -1;
  };
  const auto join = [&](const auto&) {
    if (pid > 0) waitpid(pid, nullptr, 0);
  };
  return Measure(std::string("two processes, ") +
                     (loopback ? "UDP loopback only" : "default transports (SHM)") +
                     (a.use_secure ? ", DDS-Security" : ""),
                 a, start, join);
}

Result InProcess(Args a) {
  a.loopback = true;
  std::thread publisher;
  std::unique_ptr<dl::Participant> participant;
  const auto start = [&] {
    participant = std::make_unique<dl::Participant>(Options(a, "dds_bench_publisher", "tracker"));
    publisher = std::thread([&] { Publish(*participant, a.samples, a.rate_hz, a.use_secure); });
  };
  const auto join = [&](const auto&) { publisher.join(); };
  return Measure(
      std::string("one process, two participants") + (a.use_secure ? ", DDS-Security" : ""), a,
      start, join);
}

// The other host publishes: wait for all samples, or 2 s without a new one after the
// first, or 120 s.
Result OtherHost(const Args& a) {
  const auto join = [&](const auto& received) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    std::size_t seen = 0;
    auto last_growth = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() < end &&
           received() < static_cast<std::size_t>(a.samples)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      const std::size_t now_seen = received();
      if (now_seen != seen) {
        seen = now_seen;
        last_growth = std::chrono::steady_clock::now();
      } else if (seen > 0 &&
                 std::chrono::steady_clock::now() - last_growth > std::chrono::seconds(2)) {
        break;
      }
    }
  };
  return Measure(
      "from the other host", a, [] {}, join);
}

void Print(const Args& a, const std::vector<Result>& results) {
  if (a.json) {
    std::printf("{\"samples\": %d, \"rate_hz\": %g, \"topic\": \"%s\", \"runs\": [", a.samples,
                a.rate_hz, std::string(dl::kTargetTopic).c_str());
    for (std::size_t i = 0; i < results.size(); ++i) {
      const Result& r = results[i];
      std::printf(
          "%s{\"name\": \"%s\", \"received\": %zu, \"lost\": %llu, \"p50_us\": %.1f, \"p90_us\": "
          "%.1f, "
          "\"p99_us\": %.1f, \"max_us\": %.1f}",
          i == 0 ? "" : ", ", r.name.c_str(), r.received, static_cast<unsigned long long>(r.lost),
          r.p50_us, r.p90_us, r.p99_us, r.max_us);
    }
    std::printf("]}\n");
    return;
  }
  std::printf("DDS one-way latency, %s, %d samples at %g Hz\n",
              std::string(dl::kTargetTopic).c_str(), a.samples, a.rate_hz);
  std::printf("%-64s %9s %6s %9s %9s %9s %9s\n", "run", "received", "lost", "p50 µs", "p90 µs",
              "p99 µs", "max µs");
  for (const Result& r : results) {
    std::printf("%-64s %9zu %6llu %9.1f %9.1f %9.1f %9.1f\n", r.name.c_str(), r.received,
                static_cast<unsigned long long>(r.lost), r.p50_us, r.p90_us, r.p99_us, r.max_us);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = Parse(argc, argv);
  if (a.publisher) {
    dl::Participant participant(Options(a, "dds_bench_publisher", "tracker"));
    Publish(participant, a.samples, a.rate_hz, a.use_secure);
    return 0;
  }
  if (a.subscriber) {
    Print(a, {OtherHost(a)});
    return 0;
  }
  if (!a.use_secure) {
    Print(a, {TwoProcesses(argv[0], a, true), TwoProcesses(argv[0], a, false), InProcess(a)});
    return 0;
  }
  // Each run without, then with DDS-Security, in this session.
  Args plain = a;
  plain.use_secure = false;
  Print(a, {TwoProcesses(argv[0], plain, true), TwoProcesses(argv[0], a, true),
            TwoProcesses(argv[0], plain, false), TwoProcesses(argv[0], a, false), InProcess(plain),
            InProcess(a)});
  return 0;
}
