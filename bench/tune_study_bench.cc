// The local executor's parallel speed-up (issue 20, "Local parallel speed-up on 2 cores
// >= 1.8x over one worker"): the same study (a grid of --sets parameter sets over
// --recordings simulated recordings, every trial a real `echoservo tune trial` process) run
// by tune::RunStudy on a local executor with 1 job and with --jobs jobs, in alternating
// order (ABBA) in one process, a fresh STUDY each time, so that a change of load on the host
// hits both. The recordings are made once by `echoservo scanner --record F --frames N
// --seed k` (the Embree simulated scanner, with ground truth; the catheter's target moving
// on a mitral trace) under --work.
// Per run: the study's wall time; per trial (from its outcome.json and result.json): the
// process's wall time and the trial's own load, replay and score times, so the sweep's
// overhead per trial (process start and exit, reading the request, writing the result:
// wall - load - replay - score) is printed beside the replay itself.
// Prints JSON. Options: --echoservo PATH (default: echoservo beside this program) --work DIR
// (default: /tmp/echoservo_tune_study_bench) --recordings K (4) --frames N (16) --sets S (2)
// --jobs J (2) --rounds R (2: each configuration runs 2R times) --metric M
// (loop.tip_to_target_rms_mm). Bad options exit 2 naming the option.
// Binary: build/bin/echoservo_tune_study_bench.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tune/executor.h"
#include "tune/study.h"
#include "tune/study_files.h"
#include "tune/study_spec.h"

namespace fs = std::filesystem;
namespace tune = echoservo::tune;
using Json = nlohmann::json;

namespace {

struct BenchOptions {
  std::string echoservo;
  std::string work = "/tmp/echoservo_tune_study_bench";
  int recordings = 4;
  int frames = 16;
  int sets = 2;
  int jobs = 2;
  int rounds = 2;
  std::string metric = "loop.tip_to_target_rms_mm";
};

[[noreturn]] void BenchUsage(const std::string& why) {
  std::fprintf(stderr,
               "echoservo_tune_study_bench: %s\nusage: echoservo_tune_study_bench [--echoservo "
               "PATH] [--work DIR] [--recordings K] [--frames N] [--sets S] [--jobs J] "
               "[--rounds R] [--metric M]\n",
               why.c_str());
  std::exit(2);
}

int BenchInt(const char* text, const std::string& option, int lo, int hi) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || v < lo || v > hi)
    BenchUsage(option + " " + text + ": not an integer in [" + std::to_string(lo) + ", " +
               std::to_string(hi) + "]");
  return static_cast<int>(v);
}

BenchOptions BenchParse(int argc, char** argv) {
  BenchOptions o;
  std::error_code ec;
  o.echoservo = (fs::read_symlink("/proc/self/exe", ec).parent_path() / "echoservo").string();
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) BenchUsage(a + ": needs a value (or unknown option)");
    const char* v = argv[++i];
    if (a == "--echoservo") {
      o.echoservo = v;
    } else if (a == "--work") {
      o.work = v;
    } else if (a == "--recordings") {
      o.recordings = BenchInt(v, a, 1, 100);
    } else if (a == "--frames") {
      o.frames = BenchInt(v, a, 2, 1000);
    } else if (a == "--sets") {
      o.sets = BenchInt(v, a, 1, 100);
    } else if (a == "--jobs") {
      o.jobs = BenchInt(v, a, 2, 256);
    } else if (a == "--rounds") {
      o.rounds = BenchInt(v, a, 1, 100);
    } else if (a == "--metric") {
      o.metric = v;
    } else {
      BenchUsage("unknown option " + a);
    }
  }
  if (!fs::exists(o.echoservo)) BenchUsage("--echoservo " + o.echoservo + ": not found");
  return o;
}

double BenchMedian(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct BenchRun {
  int jobs = 0;
  double wall_s = 0.0;
  std::size_t trials = 0, failed = 0;
  std::vector<double> trial_wall_s, load_s, replay_s, score_s;
};

BenchRun BenchStudy(const tune::StudySpec& spec, const BenchOptions& o, int jobs, int run) {
  const fs::path study = fs::path(o.work) / ("STUDY_" + std::to_string(run));
  fs::remove_all(study);
  tune::LocalExecutorOptions lo;
  lo.echoservo_exe = o.echoservo;
  lo.jobs = jobs;
  lo.timeout_s = 600.0;
  auto executor = tune::MakeLocalExecutor(lo);
  const auto t0 = std::chrono::steady_clock::now();
  const tune::StudySummary s = tune::RunStudy(spec, study, *executor);
  BenchRun r;
  r.jobs = jobs;
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.trials = s.trials;
  r.failed = s.failed;
  for (const tune::StudyTrial& t : tune::ReadTrials(study)) {
    if (!t.result || t.result->status != "ok" || !t.outcome) continue;
    r.trial_wall_s.push_back(t.outcome->wall_s);
    r.load_s.push_back(t.result->load_s);
    r.replay_s.push_back(t.result->replay_s);
    r.score_s.push_back(t.result->score_s);
  }
  fs::remove_all(study);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  const BenchOptions o = BenchParse(argc, argv);
  fs::create_directories(fs::path(o.work) / "recordings");
  // The recordings, made once.
  for (int k = 0; k < o.recordings; ++k) {
    const fs::path rec = fs::path(o.work) / "recordings" /
                         ("rec" + std::to_string(k) + "_f" + std::to_string(o.frames) + ".igs.mha");
    if (fs::exists(rec)) continue;
    const std::string cmd = "'" + o.echoservo + "' scanner --record '" + rec.string() +
                            "' --frames " + std::to_string(o.frames) + " --seed " +
                            std::to_string(k + 1) + " --target-motion mitral:72:8 > /dev/null";
    if (std::system(cmd.c_str()) != 0) {
      std::fprintf(stderr, "echoservo_tune_study_bench: failed: %s\n", cmd.c_str());
      return 1;
    }
  }
  // The SPEC: the recordings of this --frames, a grid over the follower's standoff.
  Json recs = Json::array();
  for (int k = 0; k < o.recordings; ++k)
    recs.push_back("recordings/rec" + std::to_string(k) + "_f" + std::to_string(o.frames) +
                   ".igs.mha");
  Json values = Json::array();
  for (int k = 1; k < o.sets; ++k) values.push_back(4.0 + 2.0 * k);  // 8 mm is the default
  Json spec_json = {{"recordings", recs},
                    {"scoring", {{"metric", o.metric}, {"from_s", 0.0}}},
                    {"search", {{"method", "grid"}}}};
  if (!values.empty()) spec_json["parameters"] = {{"follower.standoff_mm", {{"values", values}}}};
  const fs::path spec_path = fs::path(o.work) / "spec.json";
  std::ofstream(spec_path) << spec_json.dump(2);
  const tune::StudySpec spec = tune::ReadStudySpec(spec_path.string());

  std::vector<BenchRun> runs;
  int run = 0;
  for (int round = 0; round < o.rounds; ++round) {
    // ABBA: 1, J, J, 1.
    for (int jobs : {1, o.jobs, o.jobs, 1}) runs.push_back(BenchStudy(spec, o, jobs, run++));
  }
  std::map<int, std::vector<double>> wall;
  std::vector<double> trial_wall, load, replay, score, overhead;
  for (const BenchRun& r : runs) {
    wall[r.jobs].push_back(r.wall_s);
    if (r.jobs != 1) continue;  // per-trial costs from the unloaded single-job runs
    for (std::size_t i = 0; i < r.trial_wall_s.size(); ++i) {
      trial_wall.push_back(r.trial_wall_s[i]);
      load.push_back(r.load_s[i]);
      replay.push_back(r.replay_s[i]);
      score.push_back(r.score_s[i]);
      overhead.push_back(r.trial_wall_s[i] - r.load_s[i] - r.replay_s[i] - r.score_s[i]);
    }
  }
  const double one = BenchMedian(wall[1]), many = BenchMedian(wall[o.jobs]);
  Json out = {{"echoservo", o.echoservo},
              {"recordings", o.recordings},
              {"frames", o.frames},
              {"sets", spec.axes.empty() ? 1 : o.sets},
              {"trials_per_study", runs.front().trials},
              {"failed_trials", 0},
              {"metric", o.metric},
              {"runs_per_configuration", 2 * o.rounds},
              {"study_wall_s_median", {{"jobs_1", one}, {"jobs_" + std::to_string(o.jobs), many}}},
              {"speedup", one / many},
              {"per_trial_s_median_jobs_1",
               {{"process_wall", BenchMedian(trial_wall)},
                {"load", BenchMedian(load)},
                {"replay", BenchMedian(replay)},
                {"score", BenchMedian(score)},
                {"overhead", BenchMedian(overhead)}}},
              {"overhead_over_replay", BenchMedian(overhead) / BenchMedian(replay)}};
  std::size_t failed = 0;
  for (const BenchRun& r : runs) failed += r.failed;
  out["failed_trials"] = failed;
  Json all = Json::array();
  for (const BenchRun& r : runs) all.push_back({{"jobs", r.jobs}, {"wall_s", r.wall_s}});
  out["runs"] = all;
  std::printf("%s\n", out.dump(2).c_str());
  return failed == 0 ? 0 : 1;
}
