// The Slurm executor (tune/slurm_executor.h). SlurmFake.*: against stand-in sbatch/scontrol
// scripts that run the array here (chunking by MaxArraySize, quoting, a refusal, a task that
// leaves no outcome); they run everywhere. SlurmCluster.*: against a real single-node Slurm
// (scripts/slurm_local.sh): the job array's outcomes against the local executor's on fake
// trials, an unknown partition, and a real `echoservo tune --slurm` against `--jobs 2`. The
// cluster is started once per ctest run by the tune_slurm_cluster fixture
// (tests/tune/CMakeLists.txt, ECHOSERVO_SLURM_DIR), or by this process when run by hand; the
// tests skip, saying why, where it cannot start (not root, slurm-wlm missing), unless
// ECHOSERVO_REQUIRE_SLURM=1. docs/tuning_slurm.md.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"
#include "tune/executor.h"
#include "tune/slurm_executor.h"
#include "tune/study_files.h"

namespace echoservo::tune {
namespace {

namespace fs = std::filesystem;

std::string ReadText(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void WriteExecutable(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
  fs::permissions(p, fs::perms::owner_all);
}

// Removes a test's folder, unless ECHOSERVO_KEEP_TEST_DIRS=1 (to look at it after a failure).
void RemoveTestDir(const fs::path& dir) {
  const char* keep = std::getenv("ECHOSERVO_KEEP_TEST_DIRS");
  if (keep != nullptr && std::string(keep) == "1") return;
  std::error_code ec;
  fs::remove_all(dir, ec);
}

fs::path MakeTempDir(const std::string& stem) {
  std::string templ = (fs::temp_directory_path() / (stem + "-XXXXXX")).string();
  if (::mkdtemp(templ.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  return templ;
}

// A stand-in for `echoservo tune trial --request R --out O`: the request's first word says
// what the trial does (a real request is JSON; these tests only need the process's end).
constexpr const char* kFakeTrial = R"SH(#!/bin/bash
if [[ "$1 $2 $3 $5" != "tune trial --request --out" ]]; then
  echo "fake trial: unexpected arguments: $*" >&2
  exit 64
fi
ulimit -c 0
read -r mode value <"$4"
echo "fake trial $mode $value"
case "$mode" in
  ok) printf '{"value": %s}\n' "$value" >"$6" ;;
  exit) exit "$value" ;;
  segv) exec /bin/sh -c 'kill -SEGV $$' ;;
  hang) exec sleep 30 ;;
  vanish) rm -rf "$(dirname "$4")" ;;
esac
)SH";

// A study folder with one trial per mode ("ok 1.5", "segv", ...).
struct FakeStudy {
  fs::path root;
  std::vector<TrialTask> tasks;
};

FakeStudy MakeFakeStudy(const fs::path& root, const std::vector<std::string>& modes) {
  FakeStudy s;
  s.root = root;
  for (std::size_t i = 0; i < modes.size(); ++i) {
    const std::string id = TrialId(static_cast<int>(i), 0);
    const fs::path dir = TrialDir(root, id);
    fs::create_directories(dir);
    std::ofstream(dir / "request.json") << modes[i] << "\n";
    s.tasks.push_back({id, dir / "request.json", dir / "result.json", dir / "log.txt"});
  }
  return s;
}

struct RunRecord {
  std::vector<TaskOutcome> outcomes;
  std::map<std::string, int> on_done_calls;
};

RunRecord RunAll(TrialExecutor& e, const std::vector<TrialTask>& tasks) {
  RunRecord r;
  r.outcomes = e.Run(tasks, [&](const TaskOutcome& o) { ++r.on_done_calls[o.id]; });
  return r;
}

// Each task's outcome as the executor returned it is the one on disk, and on_done saw it once.
void ExpectRecorded(const FakeStudy& s, const RunRecord& r, bool outcome_files = true) {
  ASSERT_EQ(r.outcomes.size(), s.tasks.size());
  for (std::size_t i = 0; i < s.tasks.size(); ++i) {
    const TaskOutcome& o = r.outcomes[i];
    EXPECT_EQ(o.id, s.tasks[i].id);
    EXPECT_EQ(r.on_done_calls.count(o.id) ? r.on_done_calls.at(o.id) : 0, 1) << o.id;
    const fs::path file = s.tasks[i].request.parent_path() / "outcome.json";
    if (!outcome_files || !fs::exists(s.tasks[i].request.parent_path())) continue;
    ASSERT_TRUE(fs::exists(file)) << file;
    const TaskOutcome disk = TaskOutcomeFromJson(ReadText(file), file.string());
    EXPECT_EQ(disk.exit_code, o.exit_code) << o.id;
    EXPECT_EQ(disk.signal, o.signal) << o.id;
    EXPECT_EQ(disk.timed_out, o.timed_out) << o.id;
    EXPECT_EQ(disk.error, o.error) << o.id;
  }
}

// ---- stand-in sbatch: runs the array here, one task after another.

constexpr const char* kFakeSbatch = R"SH(#!/bin/bash
here=$(dirname "$0")
printf '%q ' "$@" >>"$here/calls.txt"
echo >>"$here/calls.txt"
array="" partition=""
for a in "$@"; do
  case "$a" in
    --array=*) array=${a#--array=} ;;
    --partition=*) partition=${a#--partition=} ;;
  esac
done
if [[ "$partition" == nope ]]; then
  echo "sbatch: error: Batch job submission failed: Invalid partition name specified" >&2
  exit 1
fi
script=${*: -2:1}
offset=${*: -1}
range=${array%%%*}
echo "$((700 + offset))"
for i in $(seq 0 "${range#0-}"); do
  SLURM_ARRAY_TASK_ID=$i bash "$script" "$offset" || status=1
done
exit ${status:-0}
)SH";
constexpr const char* kFakeScontrol = R"SH(#!/bin/bash
case "$*" in
  "show config") echo "MaxArraySize            = 3" ;;
  "-o show job "*) echo "JobId=${4} ArrayJobId=${4} ArrayTaskId=0-1 JobState=FAILED Reason=NonZeroExitCode" ;;
  *) exit 1 ;;
esac
)SH";
constexpr const char* kFakeSacct = R"SH(#!/bin/bash
echo "Slurm accounting storage is disabled" >&2
exit 1
)SH";
// The job is still queued, as far as squeue can tell: sbatch's return ends the array.
constexpr const char* kFakeSqueue = R"SH(#!/bin/bash
echo 700
)SH";

class SlurmFake : public ::testing::Test {
 protected:
  void SetUp() override {
    tmp_ = MakeTempDir("echoservo-slurm-fake");
    bin_ = tmp_ / "bin";
    fs::create_directories(bin_);
    WriteExecutable(bin_ / "sbatch", kFakeSbatch);
    WriteExecutable(bin_ / "scontrol", kFakeScontrol);
    WriteExecutable(bin_ / "sacct", kFakeSacct);
    WriteExecutable(bin_ / "squeue", kFakeSqueue);
    WriteExecutable(bin_ / "fake-echoservo", kFakeTrial);
  }
  void TearDown() override { RemoveTestDir(tmp_); }
  SlurmExecutorOptions Options() const {
    SlurmExecutorOptions o;
    o.echoservo_exe = (bin_ / "fake-echoservo").string();
    o.sbatch = (bin_ / "sbatch").string();
    o.timeout_s = 2.0;
    return o;
  }
  fs::path tmp_, bin_;
};

TEST(SlurmExecutorOptions, BadOptionsAreRefusedNamingTheOption) {
  SlurmExecutorOptions o;
  o.echoservo_exe = "/bin/true";
  EXPECT_NO_THROW(MakeSlurmExecutor(o));
  const auto message = [](const SlurmExecutorOptions& bad) {
    try {
      MakeSlurmExecutor(bad);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  SlurmExecutorOptions b = o;
  b.echoservo_exe.clear();
  EXPECT_NE(message(b).find("echoservo_exe"), std::string::npos) << message(b);
  b = o;
  b.timeout_s = 0.0;
  EXPECT_NE(message(b).find("timeout_s"), std::string::npos) << message(b);
  b = o;
  b.max_parallel = -1;
  EXPECT_NE(message(b).find("max_parallel"), std::string::npos) << message(b);
  b = o;
  b.partition = "two words";
  EXPECT_NE(message(b).find("partition"), std::string::npos) << message(b);
  b = o;
  b.extra_args = {"--array=0-3"};
  EXPECT_NE(message(b).find("--array"), std::string::npos) << message(b);
}

// MaxArraySize 3 splits 4 tasks into arrays of 3 and 1 (offsets 0 and 3); paths with a
// quote, spaces and a newline reach the trial intact; a task that removed its own folder
// gets the Slurm state as its error.
TEST_F(SlurmFake, SplitsByMaxArraySizeQuotesPathsAndExplainsMissingOutcomes) {
  ECHOSERVO_RELEASE_SUITE_ONLY("four fake trials through bash scripts take about a second");
  const FakeStudy s = MakeFakeStudy(tmp_ / "study with 'quote',\nnewline and  spaces",
                                    {"ok 1.5", "exit 3", "segv", "vanish"});
  const auto executor = MakeSlurmExecutor(Options());
  const RunRecord r = RunAll(*executor, s.tasks);
  ExpectRecorded(s, r);

  std::vector<std::string> calls;
  std::istringstream lines(ReadText(bin_ / "calls.txt"));
  for (std::string line; std::getline(lines, line);) calls.push_back(line);
  ASSERT_EQ(calls.size(), 2u) << ReadText(bin_ / "calls.txt");
  for (const auto& [call, array, offset] :
       {std::tuple{calls[0], "--array=0-2", " 0 "}, std::tuple{calls[1], "--array=0-0", " 3 "}}) {
    EXPECT_NE(call.find(array), std::string::npos) << call;
    EXPECT_EQ(call.substr(call.size() - std::string(offset).size()), offset) << call;
    EXPECT_NE(call.find("--wait"), std::string::npos);
    EXPECT_NE(call.find("--parsable"), std::string::npos);
    EXPECT_NE(call.find("--time=1"), std::string::npos);  // 2 s + kill grace: one minute
  }
  EXPECT_EQ(executor->name(), "slurm (jobs 700, 703)");

  EXPECT_EQ(r.outcomes[0].exit_code, 0);
  EXPECT_EQ(ReadText(s.tasks[0].result), "{\"value\": 1.5}\n");
  EXPECT_NE(ReadText(s.tasks[0].log).find("fake trial ok 1.5"), std::string::npos);
  EXPECT_EQ(r.outcomes[1].exit_code, 3);
  EXPECT_EQ(r.outcomes[2].exit_code, -1);
  EXPECT_EQ(r.outcomes[2].signal, SIGSEGV);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(r.outcomes[i].error, "") << i;
    EXPECT_FALSE(r.outcomes[i].timed_out) << i;
    EXPECT_GT(r.outcomes[i].wall_s, 0.0) << i;
    EXPECT_LT(r.outcomes[i].wall_s, 2.0) << i;  // under the timeout
  }
  EXPECT_EQ(r.outcomes[3].error,
            "no outcome written (Slurm state: FAILED, reason NonZeroExitCode; job 703_0)");
}

TEST_F(SlurmFake, RefusedSubmissionIsEveryTasksErrorAndKeepsOtherTrials) {
  const FakeStudy s = MakeFakeStudy(tmp_ / "study", {"ok 1", "ok 2", "ok 3"});
  // A finished trial of an earlier run, not among the tasks: untouched.
  const fs::path kept = TrialDir(s.root, TrialId(9, 0));
  fs::create_directories(kept);
  std::ofstream(kept / "result.json") << "{\"kept\": true}\n";
  SlurmExecutorOptions o = Options();
  o.partition = "nope";
  const RunRecord r = RunAll(*MakeSlurmExecutor(o), s.tasks);
  ExpectRecorded(s, r);
  for (const TaskOutcome& out : r.outcomes) {
    EXPECT_EQ(out.error,
              "sbatch refused the job: sbatch: error: Batch job submission failed: Invalid "
              "partition name specified");
    EXPECT_EQ(out.exit_code, -1);
  }
  EXPECT_EQ(ReadText(kept / "result.json"), "{\"kept\": true}\n");
  for (const TrialTask& t : s.tasks) EXPECT_FALSE(fs::exists(t.result)) << t.id;

  o.sbatch = (bin_ / "no-such-sbatch").string();
  const RunRecord missing = RunAll(*MakeSlurmExecutor(o), s.tasks);
  for (const TaskOutcome& out : missing.outcomes)
    EXPECT_EQ(out.error.rfind("sbatch refused the job: cannot run '" + o.sbatch + "'", 0), 0u)
        << out.error;
}

// ---- a real single-node Slurm.

class SlurmCluster : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (testing::kUnderSanitizers) return;  // every case skips: start nothing
    skip_reason_.clear();
    own_dir_.clear();
    fs::path dir;
    if (const char* d = std::getenv("ECHOSERVO_SLURM_DIR"); d != nullptr && *d != '\0') {
      dir = d;  // the ctest fixture started it (or recorded why it could not)
    } else {
      dir = MakeTempDir("echoservo-slurm");
      own_dir_ = dir;
      const std::string cmd = "bash '" + Script().string() + "' start '" + dir.string() + "' >'" +
                              (dir / "start.log").string() + "' 2>&1";
      ::setenv("ECHOSERVO_SLURM_OVERSUBSCRIBE", "8", 1);
      const int rc = std::system(cmd.c_str());
      if (rc != 0 && !fs::exists(dir / "skip_reason")) {
        skip_reason_ = "scripts/slurm_local.sh start failed: " + ReadText(dir / "start.log");
        return;
      }
    }
    if (fs::exists(dir / "skip_reason")) {
      skip_reason_ = ReadText(dir / "skip_reason");
      return;
    }
    if (!fs::exists(dir / "slurm.conf")) {
      skip_reason_ = "no slurm.conf in " + dir.string() + " (the cluster was not started)";
      return;
    }
    ::setenv("SLURM_CONF", (dir / "slurm.conf").c_str(), 1);
  }
  static void TearDownTestSuite() {
    if (own_dir_.empty()) return;
    const std::string cmd = "bash '" + Script().string() + "' stop '" + own_dir_.string() + "'";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << "stopping the local Slurm in " << own_dir_;
    std::error_code ec;
    fs::remove_all(own_dir_, ec);
  }
  void SetUp() override {
    ECHOSERVO_RELEASE_SUITE_ONLY("a Slurm job array takes about a second to schedule");
    if (!skip_reason_.empty()) {
      const char* require = std::getenv("ECHOSERVO_REQUIRE_SLURM");
      if (require != nullptr && std::string(require) == "1")
        FAIL() << "ECHOSERVO_REQUIRE_SLURM=1 but " << skip_reason_;
      GTEST_SKIP() << "no local Slurm: " << skip_reason_;
    }
    tmp_ = MakeTempDir("echoservo-slurm-test");
    WriteExecutable(tmp_ / "fake-echoservo", kFakeTrial);
  }
  void TearDown() override {
    if (!tmp_.empty()) RemoveTestDir(tmp_);
  }
  static fs::path Script() {
    return fs::path(ECHOSERVO_DATA_DIR).parent_path() / "scripts" / "slurm_local.sh";
  }
  static inline std::string skip_reason_;
  static inline fs::path own_dir_;
  fs::path tmp_;
};

// The same fake trials on the local executor and as a Slurm job array: the same outcome,
// trial for trial (exit status, signal, timeout), and the same result files.
TEST_F(SlurmCluster, JobArrayGivesTheLocalExecutorsOutcomes) {
  const std::vector<std::string> modes = {"ok 1.5", "exit 3", "segv", "hang"};
  const FakeStudy local = MakeFakeStudy(tmp_ / "local", modes);
  std::vector<std::string> slurm_modes = modes;
  slurm_modes.push_back("vanish");
  const FakeStudy slurm = MakeFakeStudy(tmp_ / "slurm", slurm_modes);
  constexpr double kTimeoutS = 1.0;

  RunRecord local_run;
  std::thread local_thread([&] {
    LocalExecutorOptions o;
    o.echoservo_exe = (tmp_ / "fake-echoservo").string();
    o.jobs = static_cast<int>(modes.size());
    o.timeout_s = kTimeoutS;
    local_run = RunAll(*MakeLocalExecutor(o), local.tasks);
  });
  SlurmExecutorOptions o;
  o.echoservo_exe = (tmp_ / "fake-echoservo").string();
  o.timeout_s = kTimeoutS;
  const auto executor = MakeSlurmExecutor(o);
  const RunRecord slurm_run = RunAll(*executor, slurm.tasks);
  local_thread.join();
  EXPECT_EQ(executor->name().rfind("slurm (job ", 0), 0u) << executor->name();
  ExpectRecorded(local, local_run);
  ExpectRecorded(slurm, slurm_run);

  for (std::size_t i = 0; i < modes.size(); ++i) {
    const TaskOutcome& l = local_run.outcomes[i];
    const TaskOutcome& s = slurm_run.outcomes[i];
    SCOPED_TRACE(modes[i]);
    EXPECT_EQ(s.exit_code, l.exit_code);
    EXPECT_EQ(s.signal, l.signal);
    EXPECT_EQ(s.timed_out, l.timed_out);
    EXPECT_EQ(s.error, "");
    EXPECT_EQ(l.error, "");
    EXPECT_EQ(ReadText(slurm.tasks[i].result), ReadText(local.tasks[i].result));
    EXPECT_NE(ReadText(slurm.tasks[i].log).find("fake trial " + modes[i]), std::string::npos);
  }
  // What the fake trials do, as ground truth for both.
  EXPECT_EQ(slurm_run.outcomes[0].exit_code, 0);
  EXPECT_EQ(ReadText(slurm.tasks[0].result), "{\"value\": 1.5}\n");
  EXPECT_EQ(slurm_run.outcomes[1].exit_code, 3);
  EXPECT_EQ(slurm_run.outcomes[2].signal, SIGSEGV);
  EXPECT_TRUE(slurm_run.outcomes[3].timed_out);
  EXPECT_EQ(slurm_run.outcomes[3].signal, SIGTERM);
  // The timed-out trial ran for the timeout (plus the kill's latency), the others less.
  EXPECT_GE(slurm_run.outcomes[3].wall_s, kTimeoutS);
  EXPECT_LT(slurm_run.outcomes[3].wall_s, kTimeoutS + 1.0);
  for (int i = 0; i < 3; ++i) EXPECT_LT(slurm_run.outcomes[i].wall_s, kTimeoutS) << modes[i];
  // The trial that removed its folder: job.sh could not write its outcome; Slurm says why.
  EXPECT_EQ(slurm_run.outcomes[4].error.rfind("no outcome written (Slurm state: FAILED", 0), 0u)
      << slurm_run.outcomes[4].error;
}

TEST_F(SlurmCluster, UnknownPartitionIsRefusedInEveryOutcome) {
  const FakeStudy s = MakeFakeStudy(tmp_ / "study", {"ok 1", "ok 2"});
  const fs::path kept = TrialDir(s.root, TrialId(9, 0));
  fs::create_directories(kept);
  std::ofstream(kept / "result.json") << "{\"kept\": true}\n";
  SlurmExecutorOptions o;
  o.echoservo_exe = (tmp_ / "fake-echoservo").string();
  o.partition = "no_such_partition";
  const RunRecord r = RunAll(*MakeSlurmExecutor(o), s.tasks);
  ExpectRecorded(s, r);
  for (const TaskOutcome& out : r.outcomes) {
    EXPECT_EQ(out.error.rfind("sbatch refused the job: ", 0), 0u) << out.error;
    EXPECT_NE(out.error.find("partition"), std::string::npos) << out.error;
  }
  EXPECT_EQ(ReadText(kept / "result.json"), "{\"kept\": true}\n");
}

// A real study: `echoservo tune SPEC --slurm` gives the results of `--jobs 2`, trial for
// trial (every metric but the host-dependent latency), on a tiny simulated recording (3
// volumes, a reduced field of view, the catheter built with a 3.5 mm sheath).
TEST_F(SlurmCluster, StudyGivesTheResultsOfLocalJobs) {
  ECHOSERVO_REQUIRES_CLI();
  using ::echoservo::testing::RunCli;
  const auto rec = RunCli("scanner --record " + (tmp_ / "sim.igs.mha").string() +
                          " --frames 3 --fov 36,16,80 --sheath-diameter 3.5");
  ASSERT_EQ(rec.rc, 0) << rec.err;
  std::ofstream(tmp_ / "spec.json") << R"({
    "recordings": ["sim.igs.mha"],
    "scoring": {"metric": "detection.tip_rms_mm", "from_s": 0},
    "parameters": {"detector.sheath_diameter_mm": {"values": [3.5]}},
    "search": {"method": "grid"},
    "timeout_s": 60
  })";
  const std::string spec = (tmp_ / "spec.json").string();
  ::echoservo::testing::RunResult local;
  std::thread local_thread([&] {
    local = RunCli("tune " + spec + " --out " + (tmp_ / "local").string() + " --jobs 2");
  });
  const auto slurm = RunCli("tune " + spec + " --out " + (tmp_ / "slurm").string() + " --slurm");
  local_thread.join();
  ASSERT_EQ(local.rc, 0) << local.err;
  ASSERT_EQ(slurm.rc, 0) << slurm.err;

  std::vector<std::string> problems;
  const std::vector<StudyTrial> l = ReadTrials(tmp_ / "local", &problems);
  const std::vector<StudyTrial> s = ReadTrials(tmp_ / "slurm", &problems);
  EXPECT_TRUE(problems.empty()) << problems.front();
  ASSERT_EQ(l.size(), 2u);  // the default (2.5 mm) and 3.5 mm
  ASSERT_EQ(s.size(), l.size());
  EXPECT_TRUE(fs::exists(tmp_ / "slurm" / "slurm" / "batch-0001" / "tasks.txt"));
  for (std::size_t i = 0; i < l.size(); ++i) {
    SCOPED_TRACE(l[i].id);
    EXPECT_EQ(s[i].id, l[i].id);
    ASSERT_TRUE(l[i].result && s[i].result);
    ASSERT_TRUE(s[i].outcome);
    EXPECT_EQ(s[i].outcome->exit_code, 0);
    EXPECT_EQ(s[i].result->status, l[i].result->status) << s[i].result->reason;
    EXPECT_EQ(s[i].result->reason, l[i].result->reason);
    EXPECT_EQ(s[i].result->volumes, l[i].result->volumes);
    EXPECT_EQ(s[i].result->measured, l[i].result->measured);
    EXPECT_EQ(s[i].result->errors, l[i].result->errors);
    std::map<std::string, double> lm = l[i].result->metrics, sm = s[i].result->metrics;
    for (auto* m : {&lm, &sm}) {
      m->erase(metric::kLatencyP50);
      m->erase(metric::kLatencyP99);
    }
    EXPECT_EQ(sm, lm);
    EXPECT_TRUE(lm.count(metric::kTipRms));
  }
  // The two settings score differently, so equal results are not a constant's.
  EXPECT_NE(l[0].result->metrics.at(metric::kTipRms), l[1].result->metrics.at(metric::kTipRms));
}

}  // namespace
}  // namespace echoservo::tune
