// The study: SPEC validation (every bad-input case of issue 20), the three searches, the
// runner on a local executor with a fake trial program (crash, timeout, exit status, the
// trial's own failure; rerun skips; Ctrl-C and kill -9 keep finished trials), the adaptive
// search through RunStudy, and the `echoservo tune` command.
#include "tune/study.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "imaging/io/sequence_writer.h"
#include "live/pipeline_parameters.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/synthetic_volume.h"
#include "tests/test_util/temp_dir.h"
#include "tune/executor.h"
#include "tune/search.h"
#include "tune/study_files.h"
#include "tune/study_spec.h"
#include "tune/trial.h"

namespace echoservo::tune {
namespace {

namespace fs = std::filesystem;
using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;
using echoservo::testing::TempDir;
using Json = nlohmann::json;

void WriteText(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

std::string ReadText(const fs::path& p) { return echoservo::testing::ReadFile(p); }

// A tiny 3D PLUS sequence (4 frames of 8³ voxels, 0.1 s apart) without truth fields.
void WriteTinySequence(const fs::path& header) {
  fs::create_directories(header.parent_path());
  imaging::SequenceWriter w(header);
  for (int i = 0; i < 4; ++i) {
    imaging::Volume v = echoservo::testing::Synthetic(8, 1.0, 20);
    v.set_timestamp_s(0.1 * i);
    v.set_frame_index(i);
    w.Append(v);
  }
}

// The first real-valued parameter with a non-empty range (the registry decides which).
const live::ParameterInfo& RealParameter(int skip = 0) {
  for (const live::ParameterInfo& p : live::Parameters()) {
    if (p.kind == live::ParameterKind::kReal && p.max > p.min && skip-- == 0) return p;
  }
  throw std::logic_error("the registry has too few real parameters");
}

const live::ParameterInfo* IntegerParameter() {
  for (const live::ParameterInfo& p : live::Parameters()) {
    if (p.kind == live::ParameterKind::kInteger && p.max > p.min) return &p;
  }
  return nullptr;
}

std::string Num(double v) { return Json(v).dump(); }

// ---------------------------------------------------------------------------------------
// The SPEC

class StudySpecTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(dir_.path());
    WriteTinySequence(dir_.path() / "recs" / "b.igs.mhd");
    WriteTinySequence(dir_.path() / "recs" / "a.igs.mhd");
  }
  // A valid SPEC with `patch` merged in (JSON merge patch: null removes a key).
  std::string Spec(const std::string& patch) const {
    const live::ParameterInfo& p = RealParameter();
    Json j = {{"recordings", {"recs/a.igs.mhd"}},
              {"scoring", {{"metric", metric::kPredictionRms}, {"latency_s", 0.1}}},
              {"parameters", {{p.name, {{"values", {p.min, p.max}}}}}},
              {"search", {{"method", "grid"}}}};
    j.merge_patch(Json::parse(patch));
    return j.dump();
  }
  std::string Error(const std::string& patch) const {
    return InvalidArgumentMessage([&] { ParseStudySpec(Spec(patch), SpecPath()); });
  }
  std::string SpecPath() const { return (dir_.path() / "spec.json").string(); }
  TempDir dir_{"tune_spec"};
};

TEST_F(StudySpecTest, AValidSpecIsExpandedAndNormalised) {
  {  // ValidSpecExpandsFoldersSortedWithShortNames
    const StudySpec s = ParseStudySpec(Spec(R"({"recordings": ["recs"]})"), SpecPath());
    ASSERT_EQ(s.recordings.size(), 2u);
    EXPECT_EQ(s.recordings[0].name, "a");
    EXPECT_EQ(s.recordings[1].name, "b");
    EXPECT_EQ(s.recordings[0].path, (dir_.path() / "recs" / "a.igs.mhd").string());
    EXPECT_EQ(s.recordings[0].info.frames, 4u);
    EXPECT_EQ(s.metric, metric::kPredictionRms);
    EXPECT_TRUE(s.minimize);
    EXPECT_FALSE(s.loop);  // the prediction metric needs no re-simulated loop
    ASSERT_EQ(s.axes.size(), 1u);
    EXPECT_EQ(s.axes[0].values.size(), 2u);
    // Execution settings are not part of what the study computes.
    const StudySpec t =
        ParseStudySpec(Spec(R"({"recordings": ["recs"], "jobs": 2, "timeout_s": 5})"), SpecPath());
    EXPECT_EQ(t.jobs, 2);
    EXPECT_EQ(t.timeout_s, 5.0);
    EXPECT_EQ(s.normalised_json, t.normalised_json);
    const StudySpec loop =
        ParseStudySpec(Spec(R"({"scoring": {"metric": "loop.tip_to_target_rms_mm"}})"), SpecPath());
    EXPECT_TRUE(loop.loop);
    const StudySpec found =
        ParseStudySpec(Spec(R"({"scoring": {"metric": "detection.found_fraction"}})"), SpecPath());
    EXPECT_FALSE(found.minimize);  // a fraction found is maximised
  }
  {  // RangeWithStepsIsAGridAxis
    const live::ParameterInfo& p = RealParameter();
    const StudySpec s =
        ParseStudySpec(Spec(R"({"parameters": {")" + p.name + R"(": {"values": null, "min": )" +
                            Num(p.min) + R"(, "max": )" + Num(p.max) + R"(, "steps": 5}}})"),
                       SpecPath());
    ASSERT_EQ(s.axes.size(), 1u);
    ASSERT_EQ(s.axes[0].values.size(), 5u);
    EXPECT_EQ(s.axes[0].values.front(), p.min);
    EXPECT_EQ(s.axes[0].values.back(), p.max);
    EXPECT_NEAR(s.axes[0].values[2], 0.5 * (p.min + p.max), 1e-12 * (std::abs(p.max) + 1));
  }
}

TEST_F(StudySpecTest, BadInputIsRefusedNamingTheItemAndWhy) {
  {  // UnknownParameterNamesItemAndClosestNames
    const live::ParameterInfo& p = RealParameter();
    const std::string typo = p.name + "x";
    const std::string e = Error(R"({"parameters": {")" + typo + R"(": {"values": [1]}}})");
    ExpectContains(e, "spec.json");
    ExpectContains(e, "parameters." + typo);
    ExpectContains(e, "unknown parameter");
    ExpectContains(e, p.name);  // the closest known name
    const std::string f = Error(R"({"fixed": {"no.such_parameter": 1}})");
    ExpectContains(f, "fixed.no.such_parameter");
  }
  {  // ValueOutsideBoundsNamesItem
    const live::ParameterInfo& p = RealParameter();
    const std::string above = Num(p.max + 1.0 + std::abs(p.max));
    ExpectContains(Error(R"({"parameters": {")" + p.name + R"(": {"values": [)" + Num(p.min) +
                         ", " + above + "]}}}"),
                   "parameters." + p.name + ".values[1]");
    ExpectContains(Error(R"({"parameters": {")" + p.name + R"(": {"values": null, "min": )" +
                         Num(p.min) + R"(, "max": )" + above + "}}}"),
                   "parameters." + p.name + ".max");
    ExpectContains(Error(R"({"parameters": null, "fixed": {")" + p.name + R"(": )" + above + "}}"),
                   "fixed." + p.name);
    ExpectContains(Error(R"({"scoring": {"latency_s": 2}})"), "scoring.latency_s");
  }
  {  // MissingOrUnreadableRecordingNamesIt
    const std::string missing = Error(R"({"recordings": ["recs/nope.igs.mha"]})");
    ExpectContains(missing, "recordings[0]");
    ExpectContains(missing, "nope.igs.mha");
    ExpectContains(missing, "does not exist");
    WriteText(dir_.path() / "bad" / "broken.igs.mha", "this is not a MetaImage header\n");
    const std::string unreadable = Error(R"({"recordings": ["recs/a.igs.mhd", "bad"]})");
    ExpectContains(unreadable, "recordings[1]");
    ExpectContains(unreadable, "broken.igs.mha");
    const std::string empty_folder = [&] {
      fs::create_directories(dir_.path() / "empty");
      return Error(R"({"recordings": ["empty"]})");
    }();
    ExpectContains(empty_folder, "holds no recording");
  }
  {  // MetricNeedingTruthTheRecordingLacksNamesIt
    const std::string e = Error(R"({"scoring": {"metric": "detection.tip_rms_mm"}})");
    ExpectContains(e, "recordings[0]");
    ExpectContains(e, "a.igs.mhd");
    ExpectContains(e, "truth");
    const std::string em = Error(R"({"scoring": {"metric": "em.tip_to_target_rms_mm"}})");
    ExpectContains(em, "a.igs.mhd");
  }
  {  // UnknownKeysAndNamesAreRefused
    ExpectContains(Error(R"({"serach": {"method": "grid"}})"), "serach: unknown key");
    ExpectContains(Error(R"({"scoring": {"latency": 0.1}})"), "scoring.latency: unknown key");
    const live::ParameterInfo& p = RealParameter();
    ExpectContains(Error(R"({"parameters": {")" + p.name + R"(": {"step": 3}}})"),
                   "parameters." + p.name + ".step: unknown key");
    const std::string metric = Error(R"({"scoring": {"metric": "loop.rms"}})");
    ExpectContains(metric, "unknown metric 'loop.rms'");
    ExpectContains(metric, metric::kLoopRms);  // the known names are listed
    ExpectContains(Error(R"({"search": {"method": "bayes"}})"), "unknown search method 'bayes'");
    ExpectContains(Error(R"({"search": {"method": "random"}})"), "search.trials");
    ExpectContains(InvalidArgumentMessage([&] { ParseStudySpec("{\"recordings\": [", "s.json"); }),
                   "s.json: not valid JSON");
  }
  {  // AdaptiveSearchRefusesDiscreteAxes
    const live::ParameterInfo& p = RealParameter();
    ExpectContains(Error(R"({"search": {"method": "adaptive", "trials": 5}})"),
                   "adaptive search takes a range");
    const live::ParameterInfo* q = IntegerParameter();
    ASSERT_NE(q, nullptr) << "the registry has integer parameters (predictor.harmonics)";
    const std::string e = Error(R"({"parameters": {")" + p.name + R"(": null, ")" + q->name +
                                R"(": {"min": )" + Num(q->min) + R"(, "max": )" + Num(q->max) +
                                R"(}}, "search": {"method": "adaptive", "trials": 5}})");
    ExpectContains(e, "parameters." + q->name);
    ExpectContains(e, "\"grid\" or \"random\"");
  }
}

// ---------------------------------------------------------------------------------------
// The searches

ParameterAxis Axis(const std::string& name, std::vector<double> values, double lo, double hi) {
  ParameterAxis a;
  a.name = name;
  a.values = std::move(values);
  a.min = lo;
  a.max = hi;
  return a;
}

TEST(StudySearch, GridAndRandomProposals) {
  {  // GridIsTheCartesianProductFirstAxisSlowest
    const std::vector<AxisValues> g =
        GridProposals({Axis("a", {1, 2, 3}, 1, 3), Axis("b", {10, 20}, 10, 20)});
    const std::vector<AxisValues> expected = {{1, 10}, {1, 20}, {2, 10}, {2, 20}, {3, 10}, {3, 20}};
    EXPECT_EQ(g, expected);
    EXPECT_TRUE(GridProposals({}).empty());
  }
  {  // RandomIsSeededUniformInRangesRoundedAndDistinct
    const std::vector<ParameterAxis> axes = {Axis("a", {}, -1.0, 3.0), Axis("b", {}, 0.5, 0.6)};
    const std::vector<AxisValues> r1 = RandomProposals(axes, 400, 7);
    EXPECT_EQ(r1, RandomProposals(axes, 400, 7));
    EXPECT_NE(r1, RandomProposals(axes, 400, 8));
    ASSERT_EQ(r1.size(), 400u);
    double mean_a = 0.0;
    for (const AxisValues& x : r1) {
      EXPECT_GE(x[0], -1.0);
      EXPECT_LE(x[0], 3.0);
      EXPECT_GE(x[1], 0.5);
      EXPECT_LE(x[1], 0.6);
      mean_a += x[0] / 400.0;
    }
    // Uniform on [-1, 3]: mean 1, SD of the mean 4/sqrt(12·400) = 0.058; 5 SD.
    EXPECT_NEAR(mean_a, 1.0, 0.29);
    // Discrete axes: a choice among the values; the space of 3 × 2 sets is exhausted, each once.
    const std::vector<AxisValues> d =
        RandomProposals({Axis("a", {1, 2, 3}, 1, 3), Axis("b", {0, 1}, 0, 1)}, 50, 1);
    EXPECT_EQ(d.size(), 6u);
    EXPECT_EQ(std::set<AxisValues>(d.begin(), d.end()).size(), 6u);
  }
  {  // RandomRoundsIntegerParameters
    const live::ParameterInfo* q = IntegerParameter();
    ASSERT_NE(q, nullptr) << "the registry has integer parameters (predictor.harmonics)";
    const std::vector<AxisValues> r = RandomProposals({Axis(q->name, {}, q->min, q->max)}, 100, 3);
    const auto span = static_cast<std::size_t>(q->max - q->min + 1);
    EXPECT_EQ(r.size(), std::min<std::size_t>(100, span));
    for (const AxisValues& x : r) {
      EXPECT_EQ(x[0], std::round(x[0]));
      EXPECT_GE(x[0], q->min);
      EXPECT_LE(x[0], q->max);
    }
  }
}

TEST(StudySearch, AdaptiveFindsTheMinimumOfASmoothFunction) {
  {  // AdaptiveFindsTheMinimumOfASmoothFunction
    // Minimum at (0.7, -1.2) inside [0, 2] × [-2, 2]; a region where the "trials fail" (NaN)
    // away from it must not derail the search.
    const std::vector<ParameterAxis> axes = {Axis("a", {}, 0.0, 2.0), Axis("b", {}, -2.0, 2.0)};
    auto f = [](const AxisValues& x) {
      if (x[0] > 1.8) return std::nan("");
      const double da = x[0] - 0.7, db = x[1] + 1.2;
      return 0.4 + da * da + 3.0 * db * db + 0.5 * da * da * da * da;
    };
    AdaptiveOptions o;
    o.max_evaluations = 40;
    o.start = {1.5, 1.0};
    const AdaptiveResult r = AdaptiveSearch(axes, o, f);
    ASSERT_EQ(r.best.size(), 2u);
    // Within 1 % of each range (0.02 and 0.04): the resolution is 0.1 %.
    EXPECT_NEAR(r.best[0], 0.7, 0.02);
    EXPECT_NEAR(r.best[1], -1.2, 0.04);
    EXPECT_NEAR(r.best_loss, 0.4, 1e-3);
    EXPECT_LE(r.evaluations, 40);
    EXPECT_EQ(r.sets.size(), static_cast<std::size_t>(r.evaluations));
    // Deterministic: the same losses, the same proposals.
    EXPECT_EQ(AdaptiveSearch(axes, o, f).sets, r.sets);
  }
  {  // FailedSetPenaltyIsWorseThanEverySeenLoss
    EXPECT_EQ(FailedSetPenalty({}), 1e6);
    EXPECT_EQ(FailedSetPenalty({0.4, 0.6, 0.5}), 0.6);
    EXPECT_EQ(FailedSetPenalty({-3.0, -1.0}), -1.0);
  }
}

// ---------------------------------------------------------------------------------------
// The runner with a fake trial program

// A stand-in for `echoservo tune trial --request R --out O`: what it does for trial <id> is
// in behaviour/<id> (ok, segv, hang, exit3, bad; default ok); it notes its pid in pids/<id>.
constexpr const char* kFakeTrial = R"sh(#!/bin/sh
req="$4"; out="$6"; id=$(basename "$(dirname "$req")"); dir=$(dirname "$0")
mkdir -p "$dir/pids"; echo $$ > "$dir/pids/$id.tmp"; mv "$dir/pids/$id.tmp" "$dir/pids/$id"
b=$(cat "$dir/behaviour/$id" 2>/dev/null || echo ok)
echo "fake trial $id: $b"
case "$b" in
  segv) kill -SEGV $$ ;;
  hang) sleep 30 ;;
  exit3) echo "fake: the recording vanished" >&2; exit 3 ;;
  bad) cp "$dir/failed.json" "$out"; exit 1 ;;
  *) cp "$dir/ok.json" "$out" ;;
esac
)sh";

class StudyRunnerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(bin());
    WriteText(exe(), kFakeTrial);
    fs::permissions(exe(), fs::perms::owner_all);
    TrialResult ok;
    ok.metrics[metric::kPredictionRms] = 0.5;
    ok.volumes = 4;
    WriteText(bin() / "ok.json", ResultToJson(ok));
    TrialResult bad;
    bad.status = "failed";
    bad.reason = "the recording has no volume after from_s (fake)";
    WriteText(bin() / "failed.json", ResultToJson(bad));
  }
  fs::path bin() const { return dir_.path() / "bin"; }
  fs::path exe() const { return bin() / "echoservo"; }
  fs::path study() const { return dir_.path() / "STUDY"; }
  void Behave(const std::string& id, const std::string& what) {
    WriteText(bin() / "behaviour" / id, what + "\n");
  }
  // A grid over one real parameter: set 0 (defaults) + 5 sets, one recording.
  StudySpec Spec() const {
    const live::ParameterInfo& p = RealParameter();
    StudySpec s;
    RecordingSpec r;
    r.path = (dir_.path() / "rec.igs.mha").string();
    r.name = "rec";
    s.recordings = {r};
    s.metric = metric::kPredictionRms;
    s.loop = false;
    ParameterAxis a = Axis(p.name, {}, p.min, p.max);
    for (int k = 1; a.values.size() < 5; ++k) {
      const double v = p.min + (p.max - p.min) * k / 7.0;
      if (v != p.default_value) a.values.push_back(v);
    }
    s.axes = {a};
    s.normalised_json = R"({"fake": 1})";
    s.timeout_s = 30.0;
    return s;
  }
  std::unique_ptr<TrialExecutor> Local(int jobs, double timeout_s) const {
    LocalExecutorOptions o;
    o.echoservo_exe = exe().string();
    o.jobs = jobs;
    o.timeout_s = timeout_s;
    return MakeLocalExecutor(o);
  }
  std::map<std::string, TrialResult> Results() const {
    std::map<std::string, TrialResult> out;
    for (const StudyTrial& t : ReadTrials(study())) {
      if (t.result) out[t.id] = *t.result;
    }
    return out;
  }
  bool WaitFor(const fs::path& p, double seconds) const {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (!fs::exists(p)) {
      if (std::chrono::steady_clock::now() > until) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return true;
  }
  TempDir dir_{"tune_runner", true};
};

TEST_F(StudyRunnerTest, FailedTrialsAreRecordedWithTheirReasonAndARerunSkipsFinished) {
  ECHOSERVO_RELEASE_SUITE_ONLY("waits out a 0.5 s trial timeout");
  Behave("s0001-r00", "segv");
  Behave("s0002-r00", "hang");
  Behave("s0003-r00", "exit3");
  Behave("s0004-r00", "bad");
  StudySpec spec = Spec();
  spec.timeout_s = 0.5;
  std::vector<std::string> log;
  auto local = Local(2, spec.timeout_s);
  const StudySummary s =
      RunStudy(spec, study(), *local, [&](const std::string& line) { log.push_back(line); });
  EXPECT_EQ(s.sets, 6u);
  EXPECT_EQ(s.trials, 6u);
  EXPECT_EQ(s.skipped, 0u);
  EXPECT_EQ(s.ran, 6u);
  EXPECT_EQ(s.failed, 4u);
  std::map<std::string, TrialResult> r = Results();
  ASSERT_EQ(r.size(), 6u);
  EXPECT_EQ(r["s0000-r00"].status, "ok");
  EXPECT_EQ(r["s0005-r00"].status, "ok");
  EXPECT_EQ(r["s0005-r00"].metrics[metric::kPredictionRms], 0.5);
  ExpectContains(r["s0001-r00"].reason, "SIGSEGV");
  ExpectContains(r["s0002-r00"].reason, "timed out");
  ExpectContains(r["s0003-r00"].reason, "status 3");
  ExpectContains(r["s0003-r00"].reason, "fake: the recording vanished");  // the log's last line
  EXPECT_EQ(r["s0004-r00"].reason, "the recording has no volume after from_s (fake)");
  // How each process ended, and its log.
  for (const StudyTrial& t : ReadTrials(study())) {
    ASSERT_TRUE(t.outcome.has_value()) << t.id;
    if (t.id == "s0001-r00") {
      EXPECT_EQ(t.outcome->signal, SIGSEGV);
    }
    if (t.id == "s0002-r00") {
      EXPECT_TRUE(t.outcome->timed_out);
      EXPECT_GE(t.outcome->wall_s, 0.5);
      EXPECT_LT(t.outcome->wall_s, 3.0);  // SIGTERM ended it, not the 3 s SIGKILL grace
    }
    if (t.id == "s0003-r00") {
      EXPECT_EQ(t.outcome->exit_code, 3);
    }
    ExpectContains(ReadText(TrialDir(study(), t.id) / "log.txt"), "fake trial " + t.id);
  }
  EXPECT_EQ(log.size(), 8u);  // the header, 6 trials, the best set

  // Rerun: the crash, the timeout and the exit without a result run again; the trial's own
  // verdict on its input ("bad") is kept.
  Behave("s0001-r00", "ok");
  Behave("s0002-r00", "ok");
  Behave("s0003-r00", "ok");
  const StudySummary again = RunStudy(spec, study(), *local);
  EXPECT_EQ(again.skipped, 3u);
  EXPECT_EQ(again.ran, 3u);
  EXPECT_EQ(again.failed, 1u);
  r = Results();
  EXPECT_EQ(r["s0001-r00"].status, "ok");
  EXPECT_EQ(r["s0004-r00"].status, "failed");
  const StudySummary third = RunStudy(spec, study(), *local);
  EXPECT_EQ(third.skipped, 6u);
  EXPECT_EQ(third.ran, 0u);
}

TEST_F(StudyRunnerTest, AStudyOfAnotherSpecIsRefusedNamingTheDifference) {
  auto local = Local(2, 10.0);
  RunStudy(Spec(), study(), *local);
  StudySpec other = Spec();
  other.normalised_json = R"({"fake": 2})";
  const std::string e = InvalidArgumentMessage([&] { RunStudy(other, study(), *local); });
  ExpectContains(e, "different SPEC");
  ExpectContains(e, "/fake");
  // A folder that is not a STUDY is not written into.
  WriteText(dir_.path() / "other" / "notes.txt", "mine\n");
  ExpectContains(InvalidArgumentMessage([&] { RunStudy(Spec(), dir_.path() / "other", *local); }),
                 "not empty");
  // A program that cannot start: every trial failed with the reason, the study went on.
  LocalExecutorOptions o;
  o.echoservo_exe = (dir_.path() / "no_such_program").string();
  auto missing = MakeLocalExecutor(o);
  const StudySummary s = RunStudy(Spec(), dir_.path() / "S2", *missing);
  EXPECT_EQ(s.failed, 6u);
  for (const StudyTrial& t : ReadTrials(dir_.path() / "S2")) {
    ASSERT_TRUE(t.result.has_value());
    ExpectContains(t.result->reason, "could not start");
  }
}

TEST_F(StudyRunnerTest, CtrlCKeepsFinishedTrialsAndARerunResumes) {
  ECHOSERVO_RELEASE_SUITE_ONLY("real processes interrupted by a signal");
  Behave("s0001-r00", "hang");
  const StudySpec spec = Spec();
  auto local = Local(1, 30.0);
  std::thread interrupter([&] {
    // Only while the hanging trial runs (the executor's handler is installed then).
    if (WaitFor(bin() / "pids" / "s0001-r00", 10.0)) kill(getpid(), SIGINT);
  });
  std::string error;
  try {
    RunStudy(spec, study(), *local);
  } catch (const std::runtime_error& e) {
    error = e.what();
  }
  interrupter.join();
  ExpectContains(error, "interrupted");
  ExpectContains(error, "SIGINT");
  std::map<std::string, TrialResult> r = Results();
  EXPECT_EQ(r.size(), 1u);  // s0000 finished before; s0001 was interrupted; the rest never began
  EXPECT_EQ(r["s0000-r00"].status, "ok");
  Behave("s0001-r00", "ok");
  const StudySummary again = RunStudy(spec, study(), *local);
  EXPECT_EQ(again.skipped, 1u);
  EXPECT_EQ(again.ran, 5u);
  EXPECT_EQ(again.failed, 0u);
}

TEST_F(StudyRunnerTest, AKilledStudyKeepsFinishedTrials) {
  ECHOSERVO_RELEASE_SUITE_ONLY("forks a study and kills it");
  Behave("s0002-r00", "hang");
  const StudySpec spec = Spec();
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    auto local = Local(1, 30.0);
    RunStudy(spec, study(), *local);
    _exit(0);
  }
  const bool hanging = WaitFor(bin() / "pids" / "s0002-r00", 10.0);
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(hanging);
  // The study's trial outlives it (a group of its own): end it as a user would.
  const pid_t orphan = std::stoi(ReadText(bin() / "pids" / "s0002-r00"));
  kill(-orphan, SIGKILL);
  EXPECT_TRUE(WIFSIGNALED(status));
  EXPECT_EQ(Results().size(), 2u);
  Behave("s0002-r00", "ok");
  auto local = Local(2, 30.0);
  const StudySummary again = RunStudy(spec, study(), *local);
  EXPECT_EQ(again.skipped, 2u);
  EXPECT_EQ(again.ran, 4u);
  EXPECT_EQ(again.failed, 0u);
  EXPECT_EQ(Results().size(), 6u);
}

// An in-process executor: each trial's metric is a known smooth function of its settings.
class FunctionExecutor : public TrialExecutor {
 public:
  FunctionExecutor(fs::path study, std::function<double(const TrialRequest&)> f)
      : study_(std::move(study)), f_(std::move(f)) {}
  std::vector<TaskOutcome> Run(const std::vector<TrialTask>& tasks,
                               const std::function<void(const TaskOutcome&)>& on_done) override {
    std::vector<TaskOutcome> out;
    for (const TrialTask& t : tasks) {
      Json j = Json::parse(ReadText(t.request));
      j.erase("id");
      j.erase("set_index");
      j.erase("recording_index");
      const TrialRequest q = RequestFromJson(j.dump(), t.request.string());
      TrialResult r;
      r.metrics[metric::kPredictionRms] = f_(q);
      WriteTrialResult(study_, t.id, r);
      TaskOutcome o;
      o.id = t.id;
      o.exit_code = 0;
      WriteTaskOutcome(study_, o);
      ++trials_run;
      if (on_done) on_done(o);
      out.push_back(o);
    }
    return out;
  }
  std::string name() const override { return "function"; }
  int trials_run = 0;

 private:
  fs::path study_;
  std::function<double(const TrialRequest&)> f_;
};

TEST_F(StudyRunnerTest, AdaptiveStudyFindsTheMinimumAndARerunReplaysItsPath) {
  const live::ParameterInfo& p = RealParameter(0);
  const live::ParameterInfo& q = RealParameter(1);
  StudySpec spec = Spec();
  RecordingSpec second = spec.recordings[0];
  second.path += ".2";
  second.name = "rec2";
  spec.recordings.push_back(second);
  spec.method = "adaptive";
  spec.trials = 40;
  spec.axes = {Axis(p.name, {}, p.min, p.max), Axis(q.name, {}, q.min, q.max)};
  // The optimum at 30 % and 80 % of the ranges; the two recordings differ by a constant.
  const double pa = p.min + 0.3 * (p.max - p.min), qa = q.min + 0.8 * (q.max - q.min);
  auto value = [&](const TrialRequest& r) {
    double x = p.default_value, y = q.default_value;
    for (const live::Assignment& a : r.settings) {
      if (a.first == p.name) x = a.second;
      if (a.first == q.name) y = a.second;
    }
    const double u = (x - pa) / (p.max - p.min), v = (y - qa) / (q.max - q.min);
    return 0.3 + (r.recording == second.path ? 0.1 : 0.0) + u * u + 2.0 * v * v;
  };
  FunctionExecutor exec(study(), value);
  const StudySummary s = RunStudy(spec, study(), exec);
  EXPECT_EQ(s.failed, 0u);
  EXPECT_EQ(s.trials, 2 * s.sets);
  EXPECT_EQ(static_cast<std::size_t>(exec.trials_run), s.trials);
  // The best set found (lowest mean over both recordings): within 1 % of each range.
  double best = 1e9, bx = 0, by = 0;
  std::map<int, std::vector<double>> per_set;
  for (const StudyTrial& t : ReadTrials(study())) {
    ASSERT_TRUE(t.result.has_value());
    per_set[t.set_index].push_back(t.result->metrics.at(metric::kPredictionRms));
  }
  for (const StudyTrial& t : ReadTrials(study())) {
    const std::vector<double>& v = per_set[t.set_index];
    ASSERT_EQ(v.size(), 2u);
    if (0.5 * (v[0] + v[1]) < best) {
      best = 0.5 * (v[0] + v[1]);
      bx = p.default_value;
      by = q.default_value;
      for (const live::Assignment& a : t.request.settings) {
        if (a.first == p.name) bx = a.second;
        if (a.first == q.name) by = a.second;
      }
    }
  }
  EXPECT_NEAR(bx, pa, 0.01 * (p.max - p.min));
  EXPECT_NEAR(by, qa, 0.01 * (q.max - q.min));
  EXPECT_NEAR(best, 0.35, 1e-3);
  // A rerun replays the optimiser's path from the STUDY: nothing runs again.
  FunctionExecutor again(study(), value);
  const StudySummary r = RunStudy(spec, study(), again);
  EXPECT_EQ(again.trials_run, 0);
  EXPECT_EQ(r.ran, 0u);
  EXPECT_EQ(r.skipped, s.trials);
  EXPECT_EQ(r.sets, s.sets);
}

// ---------------------------------------------------------------------------------------
// The command

TEST(TuneCommand, ParentAndSubcommandsParse) {
  ECHOSERVO_REQUIRES_CLI();
  ECHOSERVO_RELEASE_SUITE_ONLY("starts the echoservo program five times");
  const auto help = echoservo::testing::RunCli("tune");
  EXPECT_EQ(help.rc, 0) << help.err;
  ExpectContains(help.out, "SPEC");
  ExpectContains(help.out, "--slurm");
  const auto params = echoservo::testing::RunCli("tune params");
  EXPECT_EQ(params.rc, 0) << params.err;
  ExpectContains(params.out, RealParameter().name);
  const auto report = echoservo::testing::RunCli("tune report /nonexistent/STUDY --json");
  EXPECT_NE(report.rc, 0);
  ExpectContains(report.err, "/nonexistent/STUDY");
  const auto no_out = echoservo::testing::RunCli("tune /nonexistent/spec.json");
  EXPECT_NE(no_out.rc, 0);
  ExpectContains(no_out.err, "--out");
  const auto no_spec = echoservo::testing::RunCli("tune /nonexistent/spec.json --out x");
  EXPECT_NE(no_spec.rc, 0);
  ExpectContains(no_spec.err, "/nonexistent/spec.json");
}

TEST(TuneCommand, AStudyOverASimulatedRecordingRunsAndResumes) {
  ECHOSERVO_REQUIRES_CLI();
  ECHOSERVO_RELEASE_SUITE_ONLY("records volumes with the simulated scanner and replays them");
  TempDir dir("tune_e2e", true);
  fs::create_directories(dir.path() / "rec");
  // 3 volumes of the Embree simulated scanner (a narrow field of view: small and fast).
  const auto rec = echoservo::testing::RunCli(
      "scanner --record rec/sim.igs.mha --frames 3 --fov 40,20,80", dir.path());
  ASSERT_EQ(rec.rc, 0) << rec.err;
  WriteText(dir.path() / "spec.json", R"({
    "recordings": ["rec"],
    "scoring": {"metric": "detection.tip_rms_mm", "from_s": 0},
    "parameters": {"detector.sheath_diameter_mm": {"values": [1.5, 3.5]}}
  })");
  const auto run =
      echoservo::testing::RunCli("tune spec.json --out STUDY --jobs 2 --json", dir.path());
  ASSERT_EQ(run.rc, 0) << run.err;
  const Json s = Json::parse(run.out);
  EXPECT_EQ(s["sets"], 3);
  EXPECT_EQ(s["ran"], 3);
  EXPECT_EQ(s["failed"], 0);
  std::map<int, double> tip_mm;
  for (const StudyTrial& t : ReadTrials(dir.path() / "STUDY")) {
    ASSERT_TRUE(t.result.has_value());
    ASSERT_EQ(t.result->status, "ok") << t.result->reason;
    tip_mm[t.set_index] = t.result->metrics.at(metric::kTipRms);
  }
  ASSERT_EQ(tip_mm.size(), 3u);
  // The default detector finds the tip within the sheath's radius (1.25 mm) of the truth,
  // and a different sheath diameter changes the figure.
  EXPECT_LT(tip_mm[0], 1.25);
  EXPECT_NE(tip_mm[1], tip_mm[0]);
  EXPECT_NE(tip_mm[2], tip_mm[0]);
  const auto again = echoservo::testing::RunCli("tune spec.json --out STUDY --json", dir.path());
  ASSERT_EQ(again.rc, 0) << again.err;
  EXPECT_EQ(Json::parse(again.out)["skipped"], 3);
  EXPECT_EQ(Json::parse(again.out)["ran"], 0);
}

}  // namespace
}  // namespace echoservo::tune
