// The sweep's overhead per trial (issue 20: ≤ 10 %): the replay alone — the recording opened
// and every volume through live::TrackerNode with the default settings, in this process —
// against a whole trial process, `echoservo tune trial --recording R --out RESULT.json`
// (process start, load, replay, scoring: detection, prediction, the re-simulated 1 kHz loop),
// on the same recording, alternately in the same run. Prints each repetition and the
// medians; overhead = (trial − replay) / replay.
//
//   echoservo_tune_trial_bench [--recording R] [--echoservo EXE] [--reps N]
//
// Without --recording it records one with the simulated scanner first (the live volume size,
// 160×148×208, 10 vol/s, a beating annulus: `echoservo scanner --record ... --frames 60`).
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "imaging/io/sequence_reader.h"
#include "live/pipeline_parameters.h"
#include "live/tracker_runtime.h"
#include "live/tracker_source.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// CPU seconds (user + system) of this process or of its waited-for children: less sensitive
// than wall time to other work on a shared machine.
double CpuSeconds(int who) {
  rusage u{};
  getrusage(who, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// The replay alone: open, read every volume, track it (what `track --replay` does, no RUN).
double Replay(const fs::path& recording, std::size_t& measured) {
  const auto t0 = Clock::now();
  echoservo::live::TrackerRuntimeOptions o;
  o.node = echoservo::live::DefaultSettings().tracker;
  echoservo::live::TrackerRuntime runtime(o);
  echoservo::live::ReplaySource source(recording);
  measured = runtime.Run(source).stats.measured;
  return Seconds(t0, Clock::now());
}

std::string Quote(const std::string& s) { return "'" + s + "'"; }

}  // namespace

int main(int argc, char** argv) {
  std::string recording, exe;
  int reps = 3;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + ": needs a value");
      return argv[++i];
    };
    if (a == "--recording") {
      recording = value();
    } else if (a == "--echoservo") {
      exe = value();
    } else if (a == "--reps") {
      reps = std::stoi(value());
    } else {
      std::fprintf(stderr, "usage: %s [--recording R] [--echoservo EXE] [--reps N]\n", argv[0]);
      return 2;
    }
  }
  if (exe.empty()) exe = (fs::canonical("/proc/self/exe").parent_path() / "echoservo").string();
  const fs::path tmp =
      fs::temp_directory_path() / ("echoservo_tune_trial_bench_" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  if (recording.empty()) {
    recording = (tmp / "bench.igs.mha").string();
    const std::string cmd = Quote(exe) + " scanner --record " + Quote(recording) +
                            " --frames 60 --rate 10 --target-motion mitral:72:10 > /dev/null";
    std::printf("recording: %s\n", cmd.c_str());
    if (std::system(cmd.c_str()) != 0) {
      std::fprintf(stderr, "could not record the bench's recording\n");
      return 1;
    }
  }
  const std::string result = (tmp / "result.json").string();
  const std::string trial_cmd = Quote(exe) + " tune trial --recording " + Quote(recording) +
                                " --out " + Quote(result) + " > /dev/null";
  std::printf("trial: %s\n", trial_cmd.c_str());
  std::vector<double> replay_s, trial_s, replay_cpu_s, trial_cpu_s;
  for (int r = 0; r < reps; ++r) {
    std::size_t measured = 0;
    const double c0 = CpuSeconds(RUSAGE_SELF);
    replay_s.push_back(Replay(recording, measured));
    replay_cpu_s.push_back(CpuSeconds(RUSAGE_SELF) - c0);
    const double k0 = CpuSeconds(RUSAGE_CHILDREN);
    const auto t0 = Clock::now();
    const int rc = std::system(trial_cmd.c_str());
    trial_s.push_back(Seconds(t0, Clock::now()));
    trial_cpu_s.push_back(CpuSeconds(RUSAGE_CHILDREN) - k0);
    if (rc != 0) {
      std::fprintf(stderr, "the trial process failed (status %d)\n", rc);
      return 1;
    }
    std::printf(
        "rep %d: replay %.3f s (%.3f s CPU, %zu volumes measured), trial process %.3f s (%.3f s "
        "CPU)\n",
        r, replay_s.back(), replay_cpu_s.back(), measured, trial_s.back(), trial_cpu_s.back());
  }
  const double rep_cpu = Median(replay_cpu_s), tri_cpu = Median(trial_cpu_s);
  std::printf("median CPU: replay %.3f s, trial process %.3f s, overhead %.1f %%\n", rep_cpu,
              tri_cpu, 100.0 * (tri_cpu - rep_cpu) / rep_cpu);
  const double rep = Median(replay_s), tri = Median(trial_s);
  std::printf("median: replay %.3f s, trial process %.3f s, overhead %.1f %% (target <= 10 %%)\n",
              rep, tri, 100.0 * (tri - rep) / rep);
  std::printf("trial result (load, replay, score inside the process): %s\n", result.c_str());
  std::system(("cat " + Quote(result) + " | grep -E '_s\"' ").c_str());
  fs::remove_all(tmp);
  return 0;
}
