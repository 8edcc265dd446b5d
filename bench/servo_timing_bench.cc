// Servo timing under load: the 1 kHz servo loop (control::ServoLoop::Cycle on the live
// simulated catheter, live/sim_catheter.h, following the mitral trajectory) runs for
// --seconds S twice in one process under the same load, first as today's loop (an ordinary
// thread sleeping until absolute deadlines on std::chrono::steady_clock) and then with the
// real-time settings (control::ApplyRealtime: SCHED_FIFO --rt-priority, --servo-cpu, memory
// locked and pre-faulted), each timed by control::CycleTimer: wake-up latency (woke −
// deadline), cycle duration (end of work − woke) and overruns (work ended after the next
// deadline; late cycles are run at once, not skipped, as the servo does). Then
// cyclictest (Debian rt-tests) runs for S s at the same priority and CPU under the same load:
// its wake-up latency is the floor this machine allows a periodic SCHED_FIFO thread.
//
// Loads (normal priority, started before the servo thread so none inherits SCHED_FIFO):
// `none`; `tracker` — the demo's tracking side: the simulated water tank rendered by
// live::DelayedScanner at 25 vol/s on one thread, each volume through live::TrackerNode
// (Radon detector, predictor competition; no DDS, no RUN directory); `cpu` — --load-threads
// busy threads (default: one per CPU). The work each load did in each phase is printed
// (volumes, or busy-loop iterations) so that the phases can be seen to share the load.
//
// Times in µs (as cyclictest prints them); quantiles are upper bin edges of 1 µs bins
// (cyclictest's bins: whole µs, truncated). Bad options exit 2 naming the option.
// Binary: build/bin/echoservo_servo_timing_bench [--seconds S] [--load none|tracker|cpu]
//   [--load-threads N] [--rt-priority P] [--servo-cpu N] [--clock-nanosleep] [--no-cyclictest]
//   [--cyclictest-output FILE] [--json]
// Details and figures: docs/control.md "Real-time execution".
#include <sys/utsname.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "control/cycle_timing.h"
#include "control/realtime.h"
#include "control/servo_loop.h"
#include "control/trajectory.h"
#include "live/delayed_scanner.h"
#include "live/pipeline_clock.h"
#include "live/sim_catheter.h"
#include "live/sim_scene.h"
#include "live/tracker_runtime.h"
#include "live/tracker_source.h"

namespace control = echoservo::control;
namespace live = echoservo::live;
using Clock = std::chrono::steady_clock;

namespace {

struct Args {
  double seconds = 10.0;
  std::string load = "tracker";
  int load_threads = 0;  // 0: one per CPU
  int rt_priority = 80;
  int servo_cpu = -1;
  bool cyclictest = true;
  bool json = false;
  bool clock_nanosleep = false;   // --clock-nanosleep: absolute clock_nanosleep, not sleep_until
  std::string cyclictest_output;  // --cyclictest-output FILE: its raw output, kept
};

[[noreturn]] void Usage(const std::string& error) {
  std::fprintf(stderr,
               "servo_timing_bench: %s\n"
               "usage: echoservo_servo_timing_bench [--seconds S (0, 3600], default 10]\n"
               "  [--load none|tracker|cpu (default tracker)] [--load-threads N (cpu load, "
               "default: one per CPU)]\n"
               "  [--rt-priority P (SCHED_FIFO, default 80)] [--servo-cpu N (default: not "
               "pinned)]\n"
               "  [--clock-nanosleep (both servo runs sleep with clock_nanosleep TIMER_ABSTIME)]\n"
               "  [--no-cyclictest] [--cyclictest-output FILE (its raw histogram)] [--json]\n",
               error.c_str());
  std::exit(2);
}

// The whole argument as a number, or a usage error naming the option.
double ParseNumber(const std::string& option, const char* text) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || errno != 0 || !std::isfinite(v))
    Usage(option + " " + text + ": not a number");
  return v;
}

int ParseInt(const std::string& option, const char* text) {
  const double v = ParseNumber(option, text);
  if (v != std::floor(v) || std::fabs(v) > 1e6) Usage(option + " " + text + ": not an integer");
  return static_cast<int>(v);
}

Args Parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto value = [&]() -> const char* {
      if (i + 1 >= argc) Usage(arg + ": needs a value");
      return argv[++i];
    };
    if (arg == "--seconds") {
      a.seconds = ParseNumber(arg, value());
      if (!(a.seconds > 0 && a.seconds <= 3600)) Usage("--seconds: must be in (0, 3600]");
    } else if (arg == "--load") {
      a.load = value();
      if (a.load != "none" && a.load != "tracker" && a.load != "cpu")
        Usage("--load " + a.load + ": must be none, tracker or cpu");
    } else if (arg == "--load-threads") {
      a.load_threads = ParseInt(arg, value());
      if (a.load_threads < 1 || a.load_threads > 256) Usage("--load-threads: must be in [1, 256]");
    } else if (arg == "--rt-priority") {
      a.rt_priority = ParseInt(arg, value());
    } else if (arg == "--servo-cpu") {
      a.servo_cpu = ParseInt(arg, value());
    } else if (arg == "--no-cyclictest") {
      a.cyclictest = false;
    } else if (arg == "--clock-nanosleep") {
      a.clock_nanosleep = true;
    } else if (arg == "--cyclictest-output") {
      a.cyclictest_output = value();
    } else if (arg == "--json") {
      a.json = true;
    } else if (arg == "--help" || arg == "-h") {
      Usage("the servo loop's wake-up latency and overruns, ordinary vs real-time, under load");
    } else {
      Usage("unknown option " + arg);
    }
  }
  if (a.load_threads == 0) a.load_threads = control::MachineCpuCount();
  return a;
}

control::RealtimeOptions RealtimeOptionsOf(const Args& a) {
  control::RealtimeOptions o;
  o.enabled = true;
  o.fifo_priority = a.rt_priority;
  o.cpu = a.servo_cpu;
  o.lock_memory = true;
  return o;
}

// ---------------------------------------------------------------------------------------
// Loads. Each runs from construction to destruction; Work() is a monotonic counter of what
// it did (volumes tracked, or busy-loop iterations).

class Load {
 public:
  virtual ~Load() = default;
  virtual double Work() const = 0;
  virtual std::string WorkUnit() const = 0;
  virtual std::string Describe() const = 0;
};

class NoLoad final : public Load {
 public:
  double Work() const override { return 0.0; }
  std::string WorkUnit() const override { return "-"; }
  std::string Describe() const override { return "none"; }
};

class CpuLoad final : public Load {
 public:
  explicit CpuLoad(int threads) {
    for (int i = 0; i < threads; ++i)
      threads_.emplace_back([this] {
        double x = 1.0;
        std::uint64_t n = 0;
        while (!stop_.load(std::memory_order_relaxed)) {
          for (int j = 0; j < 4096; ++j) x = x * 1.0000001 + 1e-9;
          n += 4096;
          if ((n & ((1u << 20) - 1)) == 0) iterations_.fetch_add(1u << 20);
        }
        sink_.store(x);
      });
  }
  ~CpuLoad() override {
    stop_ = true;
    for (auto& t : threads_) t.join();
  }
  double Work() const override { return static_cast<double>(iterations_.load()) / 1e6; }
  std::string WorkUnit() const override { return "M busy-loop iterations"; }
  std::string Describe() const override {
    return "cpu: " + std::to_string(threads_.size()) + " busy threads at normal priority";
  }

 private:
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> iterations_{0};
  std::atomic<double> sink_{0.0};
  std::vector<std::thread> threads_;
};

// The demo's tracking side without DDS and RUN directory (live/demo_run.cc): the simulated
// scanner renders on its own thread, a tracker thread detects in each newest volume. The
// catheter stays where the scene puts it (the servo's plant is not fed back: that would
// take the scene's lock inside the cycle); the detector's work is the same.
class TrackerLoad final : public Load {
 public:
  explicit TrackerLoad(double duration_s)
      : scene_(live::SimSceneOptions{}),
        source_(scene_, clock_, {25.0, 0.05, 0.10, duration_s, 1}),
        runtime_([this] {
          live::TrackerRuntimeOptions o;
          o.on_tracked = [this](const live::TrackedVolume&, const live::SourceVolume&, double) {
            ++volumes_;
          };
          return o;
        }()) {
    thread_ = std::thread([this] { runtime_.Run(source_); });
  }
  ~TrackerLoad() override {
    source_.Stop();
    thread_.join();
  }
  double Work() const override { return static_cast<double>(volumes_.load()); }
  std::string WorkUnit() const override { return "volumes tracked"; }
  std::string Describe() const override {
    return "tracker: simulated scanner 25 vol/s (1 rendering thread) + the tracker runtime "
           "(Radon detector and predictor) on each newest volume, normal priority";
  }

 private:
  live::SimScene scene_;
  live::PipelineClock clock_{0.3};
  live::SimScannerSource source_;
  std::atomic<std::uint64_t> volumes_{0};
  live::TrackerRuntime runtime_;
  std::thread thread_;
};

// ---------------------------------------------------------------------------------------
// The servo run.

// clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME), as cyclictest sleeps. libstdc++'s
// sleep_until on steady_clock (CLOCK_MONOTONIC) is a relative nanosleep from a fresh now():
// a preemption between the two lengthens the sleep by its own duration.
void SleepUntilAbsolute(Clock::time_point deadline) {
  const auto ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(deadline.time_since_epoch()).count();
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / 1000000000);
  ts.tv_nsec = static_cast<long>(ns % 1000000000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

struct RunResult {
  std::string config;
  std::string realtime;  // RealtimeStatus::Summary, or "ordinary thread"
  std::vector<std::string> refusals;
  control::CycleTimingReport timing;
  double load_work = 0.0;
  std::uint64_t sensor_faults = 0;
  std::string error;
};

RunResult RunServo(const std::string& config, const Args& a, bool realtime, const Load& load) {
  RunResult r;
  r.config = config;
  // Everything the loop touches is built here, before the servo thread starts.
  live::SimCatheter catheter = live::MakeSimCatheter(1.59, 1.50, 1);
  control::ServoLoop loop(*catheter.plant, catheter.servo);
  const std::unique_ptr<control::Trajectory> reference = control::MakeTrajectory("mitral");
  const double period_s = catheter.servo.period_s;
  control::CycleTimer timer(period_s);
  const auto cycles = static_cast<std::int64_t>(std::llround(a.seconds / period_s));
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period_s));
  const double work0 = load.Work();

  std::thread servo([&] {
    try {
      // The servo's PM QoS request (control::CpuLatencyRequest), as `servo` and `demo` make it
      // (cyclictest makes the same one for itself).
      std::optional<control::CpuLatencyRequest> cpu_latency;
      if (realtime) {
        control::RealtimeStatus s = control::ApplyRealtime(RealtimeOptionsOf(a));
        cpu_latency.emplace(RealtimeOptionsOf(a).cpu_latency_us);
        cpu_latency->Report(s);
        r.realtime = s.Summary();
        r.refusals = s.refusals;
      } else {
        r.realtime = "ordinary thread (SCHED_OTHER, not pinned, memory not locked)";
      }
      catheter.compensator->Reset();
      loop.Start(0.0);
      const Clock::time_point t0 = Clock::now() + std::chrono::milliseconds(10);
      const auto seconds = [&](Clock::time_point tp) {
        return std::chrono::duration<double>(tp - t0).count();
      };
      for (std::int64_t k = 0; k < cycles; ++k) {
        const Clock::time_point deadline = t0 + k * period;
        if (a.clock_nanosleep)
          SleepUntilAbsolute(deadline);
        else
          std::this_thread::sleep_until(deadline);
        timer.Woke(seconds(deadline), seconds(Clock::now()));
        loop.Cycle(static_cast<double>(k) * period_s, static_cast<std::size_t>(k), *reference,
                   *catheter.compensator);
        timer.Finished(seconds(Clock::now()));
      }
    } catch (const std::exception& e) {
      r.error = e.what();
    }
  });
  servo.join();
  r.load_work = load.Work() - work0;
  r.timing = timer.Report();
  r.sensor_faults = loop.sensor_faults();
  return r;
}

// ---------------------------------------------------------------------------------------
// cyclictest.

struct CyclictestResult {
  bool ran = false;
  std::string command;
  std::string note;  // why it did not run, or its exit status
  std::uint64_t samples = 0, overflows = 0;
  double min_us = 0, avg_us = 0, max_us = 0, p50_us = 0, p99_us = 0, p999_us = 0;
  double load_work = 0.0;
};

std::optional<std::string> FindOnPath(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  dirs += ":/usr/sbin:/sbin";
  std::stringstream ss(dirs);
  for (std::string dir; std::getline(ss, dir, ':');) {
    if (dir.empty()) continue;
    const std::string p = dir + "/" + name;
    if (access(p.c_str(), X_OK) == 0) return p;
  }
  return std::nullopt;
}

// Parses `cyclictest -q -h US` output (one thread): histogram rows "BIN COUNT" (µs bins,
// truncated), then "# Total:", "# Min/Avg/Max Latencies:", "# Histogram Overflows:".
// Quantiles are upper bin edges over all samples (overflows included; a quantile among the
// overflows is the maximum).
void ParseCyclictest(const std::string& out, CyclictestResult& r) {
  std::vector<std::pair<long, std::uint64_t>> bins;
  std::uint64_t total = 0;
  bool have_max = false;
  std::stringstream ss(out);
  for (std::string line; std::getline(ss, line);) {
    const auto field = [&](const char* key, double& v) {
      const std::size_t at = line.find(key);
      if (at == std::string::npos) return false;
      v = std::strtod(line.c_str() + at + std::strlen(key), nullptr);
      return true;
    };
    double v = 0.0;
    if (!line.empty() && line[0] >= '0' && line[0] <= '9') {
      char* end = nullptr;
      const long bin = std::strtol(line.c_str(), &end, 10);
      const unsigned long long count = std::strtoull(end, nullptr, 10);
      if (count > 0) bins.emplace_back(bin, count);
    } else if (field("# Total:", v)) {
      total = static_cast<std::uint64_t>(v);
    } else if (field("# Min Latencies:", v)) {
      r.min_us = v;
    } else if (field("# Avg Latencies:", v)) {
      r.avg_us = v;
    } else if (field("# Max Latencies:", v)) {
      r.max_us = v;
      have_max = true;
    } else if (field("# Histogram Overflows:", v)) {
      r.overflows = static_cast<std::uint64_t>(v);
    }
  }
  r.samples = total + r.overflows;
  if (r.samples == 0 || !have_max) {
    r.ran = false;
    r.note = "cyclictest printed no histogram";
    return;
  }
  const auto quantile = [&](double p) {
    const auto rank =
        std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(p * r.samples)));
    std::uint64_t seen = 0;
    for (const auto& [bin, count] : bins) {
      seen += count;
      if (seen >= rank) return std::min(static_cast<double>(bin + 1), r.max_us + 1.0);
    }
    return r.max_us;
  };
  r.p50_us = quantile(0.5);
  r.p99_us = quantile(0.99);
  r.p999_us = quantile(0.999);
}

CyclictestResult RunCyclictest(const Args& a, const Load& load) {
  CyclictestResult r;
  const std::optional<std::string> exe = FindOnPath("cyclictest");
  if (!exe) {
    r.note = "cyclictest not found (Debian package rt-tests: apt-get install rt-tests)";
    return r;
  }
  // 10 ms of 1 µs bins: a loaded VM's stalls of several ms stay inside the histogram.
  const long loops = std::lround(a.seconds * 1000.0);
  std::string cmd = *exe + " -m -p " + std::to_string(a.rt_priority) + " -i 1000 -l " +
                    std::to_string(loops) + " -q -h 10000";
  const int cpus = control::MachineCpuCount();
  if (a.servo_cpu >= 0) {
    cmd += " -a " + std::to_string(a.servo_cpu);
    if (cpus > 1) cmd += " --mainaffinity " + std::to_string(a.servo_cpu == 0 ? 1 : 0);
  }
  r.command = cmd;
  const double work0 = load.Work();
  FILE* pipe = popen((cmd + " 2>&1").c_str(), "r");
  if (!pipe) {
    r.note = std::string("could not start cyclictest: ") + std::strerror(errno);
    return r;
  }
  std::string out;
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, pipe)) > 0;) out.append(buf, n);
  const int status = pclose(pipe);
  r.load_work = load.Work() - work0;
  if (!a.cyclictest_output.empty()) {
    std::ofstream f(a.cyclictest_output);
    f << out;
    if (!f)
      std::fprintf(stderr, "servo_timing_bench: could not write --cyclictest-output %s\n",
                   a.cyclictest_output.c_str());
  }
  r.ran = true;
  ParseCyclictest(out, r);
  if (status != 0) {
    r.ran = false;
    r.note = "cyclictest exited with status " + std::to_string(status) + ": " +
             out.substr(0, std::min<std::size_t>(out.size(), 400));
  }
  return r;
}

// ---------------------------------------------------------------------------------------
// Machine and output.

std::string ReadFirstLine(const char* path) {
  std::ifstream f(path);
  std::string line;
  if (f) std::getline(f, line);
  return line;
}

std::string JsonString(const std::string& s) {
  std::string o = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      o += '\\';
      o += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char esc[8];
      std::snprintf(esc, sizeof esc, "\\u%04x", c);
      o += esc;
    } else {
      o += c;
    }
  }
  return o + "\"";
}

std::string Num(double v) {
  if (!std::isfinite(v)) return "null";
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = Parse(argc, argv);
  try {
    RealtimeOptionsOf(a).Validate();
  } catch (const std::invalid_argument& e) {
    Usage(e.what());
  }
  if (!a.cyclictest_output.empty() && !std::ofstream(a.cyclictest_output))
    Usage("--cyclictest-output " + a.cyclictest_output + ": cannot write there");

  utsname u{};
  uname(&u);
  const std::string kernel = std::string(u.release) + " " + u.version;
  const bool preempt_rt = ReadFirstLine("/sys/kernel/realtime") == "1" ||
                          std::string(u.version).find("PREEMPT_RT") != std::string::npos;
  const int cpus = control::MachineCpuCount();
  const std::string loadavg_before = ReadFirstLine("/proc/loadavg");

  std::unique_ptr<Load> load;
  if (a.load == "cpu")
    load = std::make_unique<CpuLoad>(a.load_threads);
  else if (a.load == "tracker")
    load = std::make_unique<TrackerLoad>(3.0 * a.seconds + 60.0);
  else
    load = std::make_unique<NoLoad>();
  if (!a.json)
    std::fprintf(stderr, "servo_timing_bench: %g s per run, load %s; baseline...\n", a.seconds,
                 load->Describe().c_str());
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // let the load settle

  std::vector<RunResult> runs;
  runs.push_back(RunServo("baseline", a, false, *load));
  if (!a.json) std::fprintf(stderr, "servo_timing_bench: real-time...\n");
  runs.push_back(RunServo("realtime", a, true, *load));
  CyclictestResult ct;
  if (a.cyclictest) {
    if (!a.json) std::fprintf(stderr, "servo_timing_bench: cyclictest...\n");
    ct = RunCyclictest(a, *load);
  } else {
    ct.note = "not run (--no-cyclictest)";
  }
  const std::string loadavg_after = ReadFirstLine("/proc/loadavg");
  const std::string unit = load->WorkUnit();
  const std::string description = load->Describe();
  load.reset();

  int rc = 0;
  for (const RunResult& r : runs)
    if (!r.error.empty()) rc = 1;

  if (a.json) {
    std::string j = "{\"seconds\": " + Num(a.seconds) + ", \"load\": " + JsonString(a.load) +
                    ", \"load_description\": " + JsonString(description) +
                    ", \"load_threads\": " + std::to_string(a.load == "cpu" ? a.load_threads : 0) +
                    ", \"load_work_unit\": " + JsonString(unit) + ", \"sleep\": " +
                    JsonString(a.clock_nanosleep ? "clock_nanosleep" : "sleep_until") +
                    ", \"rt_priority\": " + std::to_string(a.rt_priority) +
                    ", \"servo_cpu\": " + std::to_string(a.servo_cpu) +
                    ", \"machine\": {\"cpus\": " + std::to_string(cpus) +
                    ", \"kernel\": " + JsonString(kernel) +
                    ", \"preempt_rt\": " + (preempt_rt ? "true" : "false") +
                    ", \"loadavg_before\": " + JsonString(loadavg_before) +
                    ", \"loadavg_after\": " + JsonString(loadavg_after) + "}, \"runs\": [";
    for (std::size_t i = 0; i < runs.size(); ++i) {
      const RunResult& r = runs[i];
      j += std::string(i ? ", " : "") + "{\"config\": " + JsonString(r.config) +
           ", \"realtime\": " + JsonString(r.realtime) + ", \"refusals\": [";
      for (std::size_t k = 0; k < r.refusals.size(); ++k)
        j += (k ? ", " : "") + JsonString(r.refusals[k]);
      j += "], \"load_work\": " + Num(r.load_work) +
           ", \"sensor_faults\": " + std::to_string(r.sensor_faults) +
           ", \"error\": " + (r.error.empty() ? "null" : JsonString(r.error)) +
           ", \"timing\": " + r.timing.Json() + "}";
    }
    j += "], \"cyclictest\": ";
    if (ct.ran) {
      j += "{\"command\": " + JsonString(ct.command) +
           ", \"samples\": " + std::to_string(ct.samples) +
           ", \"overflows\": " + std::to_string(ct.overflows) +
           ", \"load_work\": " + Num(ct.load_work) +
           ", \"wakeup_latency_us\": {\"p50\": " + Num(ct.p50_us) + ", \"p99\": " + Num(ct.p99_us) +
           ", \"p999\": " + Num(ct.p999_us) + ", \"max\": " + Num(ct.max_us) +
           ", \"min\": " + Num(ct.min_us) + ", \"mean\": " + Num(ct.avg_us) + "}}";
    } else {
      j += "null, \"cyclictest_note\": " + JsonString(ct.note);
    }
    j += "}";
    std::printf("%s\n", j.c_str());
    return rc;
  }

  std::printf("servo timing: %g s per run, 1 kHz (%s on absolute deadlines), load %s\n", a.seconds,
              a.clock_nanosleep ? "clock_nanosleep" : "std::this_thread::sleep_until",
              description.c_str());
  std::printf("machine: %d CPUs, kernel %s, PREEMPT_RT %s; loadavg before %s, after %s\n", cpus,
              kernel.c_str(), preempt_rt ? "yes" : "no", loadavg_before.c_str(),
              loadavg_after.c_str());
  std::printf("%-11s %9s %9s %9s %9s %10s %9s %9s %12s\n", "config", "wake p50", "p99", "p99.9",
              "max", "cycle p99", "overruns", "overrun%", "load work");
  for (const RunResult& r : runs) {
    const auto& w = r.timing.wakeup_latency;
    std::printf("%-11s %9.0f %9.0f %9.0f %9.0f %10.0f %9llu %9.3f %12.0f\n", r.config.c_str(),
                w.p50_us, w.p99_us, w.p999_us, w.max_us, r.timing.cycle_duration.p99_us,
                static_cast<unsigned long long>(r.timing.overruns),
                100.0 * r.timing.overrun_fraction, r.load_work);
  }
  if (ct.ran)
    std::printf("%-11s %9.0f %9.0f %9.0f %9.0f %10s %9s %9s %12.0f\n", "cyclictest", ct.p50_us,
                ct.p99_us, ct.p999_us, ct.max_us, "-", "-", "-", ct.load_work);
  std::printf("(µs; quantiles are upper edges of 1 µs bins; load work in %s)\n", unit.c_str());
  for (const RunResult& r : runs) {
    std::printf("%s: %s; %llu cycles, max %llu consecutive overruns\n", r.config.c_str(),
                r.realtime.c_str(), static_cast<unsigned long long>(r.timing.cycles),
                static_cast<unsigned long long>(r.timing.max_consecutive_overruns));
    for (const std::string& s : r.refusals) std::printf("  refused: %s\n", s.c_str());
    if (!r.error.empty()) std::printf("  error: %s\n", r.error.c_str());
  }
  if (ct.ran)
    std::printf(
        "cyclictest (the floor): %s\n  %llu samples, min %.0f avg %.0f max %.0f µs, %llu "
        "beyond 10 ms\n",
        ct.command.c_str(), static_cast<unsigned long long>(ct.samples), ct.min_us, ct.avg_us,
        ct.max_us, static_cast<unsigned long long>(ct.overflows));
  else
    std::printf("cyclictest: %s\n", ct.note.c_str());
  return rc;
}
