// One tuning trial (tune/trial.h) on small recordings of the simulated scanner made by
// `echoservo scanner --record` (a reduced field of view at the default density, a beating
// annulus, the catheter built with a 3.5 mm sheath against the detector's 2.5 mm default),
// on the `phantom` source (a generator apart from the simulator) and on a real PLUS
// sequence without truth (data/plus). The recordings are made once per ctest run by
// TuneTrialSetup (a CTest fixture).
#include "tune/trial.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>

#include "formats/em_log.h"
#include "formats/run_record.h"
#include "imaging/igtl/phantom_source.h"
#include "imaging/io/plus_sequence.h"
#include "imaging/io/truth_fields.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/shared_fixture.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::tune {
namespace {

namespace fs = std::filesystem;
using ::echoservo::testing::ExpectContains;
using ::echoservo::testing::InvalidArgumentMessage;
using ::echoservo::testing::RunCli;

// 10 vol/s, 3.2 s: the EKF at 2 harmonics publishes after its 2 s window (20 volumes; it
// needs 2·(2·2 + 4) = 16), the loop follows from then.
constexpr double kRateHz = 10.0;
constexpr int kFrames = 32;
constexpr double kFollowingFromS = 2.2;
constexpr double kTrueSheathMm = 3.5;  // as built; the detector's default is 2.5 mm
constexpr const char* kMotion = "mitral:90:8";
constexpr double kTargetP2pMm = 8.0;

const char* kSimName = "sim_sheath35.igs.mha";
const char* kPhantomName = "phantom.igs.mhd";

// Makes the recordings in `dir` (the CLI, as a user would).
void MakeRecordings(const fs::path& dir) {
  fs::create_directories(dir);
  const auto sim = RunCli("scanner --record " + (dir / kSimName).string() + " --frames " +
                          std::to_string(kFrames) + " --rate " + std::to_string(kRateHz) +
                          " --fov 36,16,80 --sheath-diameter 3.5 --target-motion " + kMotion);
  ASSERT_EQ(sim.rc, 0) << sim.err;
  // The phantom source as `echoservo scanner --source phantom --record` writes it, at half
  // its default size (its line and disc scale with the volume) and uncompressed: its noise
  // does not compress, and zlib would cost more than the test.
  imaging::openigtlink::PhantomOptions po;
  po.dims = Eigen::Vector3i(80, 74, 104);
  po.frame_count = 3;
  imaging::openigtlink::PhantomSource phantom(po);
  std::vector<imaging::Volume> volumes;
  std::vector<imaging::FrameGroundTruth> truths;
  while (auto f = phantom.Next()) {
    volumes.push_back(std::move(f->volume));
    truths.push_back(f->truth.value());
  }
  imaging::PlusSequence seq = imaging::VolumesToSequence(volumes);
  for (std::size_t i = 0; i < truths.size(); ++i)
    imaging::SetTruthFields(truths[i], seq.frames[i].fields);
  imaging::WritePlusSequence(seq, dir / kPhantomName, false);
}

// Recordings this process made (outside ctest), removed when it ends.
struct OwnRecordings {
  fs::path dir;
  ~OwnRecordings() {
    std::error_code ec;
    if (!dir.empty()) fs::remove_all(dir, ec);
  }
};
OwnRecordings own_recordings;

// The fixture folder (ctest), else recordings made once for this process.
const fs::path& Recordings() {
  static const fs::path dir = [] {
    if (const auto shared = ::echoservo::testing::SharedFixtureDir();
        shared && ::echoservo::testing::FixtureComplete(*shared))
      return *shared;
    own_recordings.dir =
        fs::temp_directory_path() / ("echoservo_tune_trial_" + std::to_string(::getpid()));
    MakeRecordings(own_recordings.dir);
    return own_recordings.dir;
  }();
  return dir;
}

TrialRequest SimRequest() {
  TrialRequest r;
  r.recording = (Recordings() / kSimName).string();
  r.from_s = 0.0;
  r.latency_s = 0.1;
  r.settings = {{"predictor.harmonics", 2}, {"predictor.max_harmonics", 2}};
  return r;
}

double Metric(const TrialResult& r, const char* name) {
  const auto it = r.metrics.find(name);
  EXPECT_NE(it, r.metrics.end()) << "no metric " << name;
  return it == r.metrics.end() ? std::nan("") : it->second;
}

// A RUN directory (docs/report.md) around the sim recording: its volumes (a link), run.json
// with the EM→image transform (identity) and standoff, and an EM log of a perfect follower:
// the tip at the true target less the standoff along the true axis, at each volume's time.
fs::path MakeRun(const fs::path& dir, double standoff_mm) {
  const imaging::PlusSequence seq = imaging::ReadPlusSequence(Recordings() / kSimName);
  fs::create_directories(dir);
  fs::create_symlink(Recordings() / kSimName, dir / "volumes.igs.mhd");
  formats::RunInfo info;
  info.standoff_mm = standoff_mm;
  info.meta.source = "trial_test";
  info.meta.em_to_image = Eigen::Isometry3d::Identity();
  info.meta.time_base = formats::RunTimeBase::kPipeline;
  formats::RunWriter w(dir, info);
  for (const imaging::SequenceFrame& f : seq.frames) {
    const auto truth = imaging::TruthFromFields(f.fields);
    const double t = f.Timestamp().value();
    w.AddTarget({t, t, t, true, truth->target_mm, truth->tip_mm, truth->axis_direction, 1.0});
    formats::EmSample e;
    e.t_s = t;
    e.position_mm = truth->target_mm - standoff_mm * truth->axis_direction.normalized();
    e.valid = true;
    w.AddEm(e);
  }
  return dir;
}

TEST(TuneTrialSetup, Recordings) {
  ECHOSERVO_RELEASE_SUITE_ONLY("renders 32 simulated volumes");
  const auto shared = ::echoservo::testing::SharedFixtureDir();
  if (!shared) GTEST_SKIP() << "outside ctest: the suite makes its own recordings";
  MakeRecordings(*shared);
  ::echoservo::testing::MarkFixtureComplete(*shared);
}

// Detection against the truth fields, prediction and the re-simulated loop are all scored,
// with figures a physicist would expect of a 0.5–0.8 mm voxel grid and an 8 mm beat.
TEST(TuneTrial, ScoresEveryStage) {
  ECHOSERVO_RELEASE_SUITE_ONLY("replays 32 volumes and simulates 3.1 s of the 1 kHz loop");
  TrialRequest r = SimRequest();
  r.from_s = kFollowingFromS;
  TrialTrace trace;
  const TrialResult res = RunTrial(r, &trace);
  EXPECT_EQ(res.volumes, static_cast<std::size_t>(kFrames));
  EXPECT_EQ(res.errors, 0u);
  EXPECT_DOUBLE_EQ(Metric(res, metric::kFoundFraction), 1.0);
  // The voxels are about 0.6 mm: a detected tip or target within 2 voxels, the axis within
  // 3° (its bright run is ~20 mm long).
  EXPECT_LT(Metric(res, metric::kTipRms), 1.2);
  EXPECT_LT(Metric(res, metric::kTargetRms), 1.2);
  EXPECT_LT(Metric(res, metric::kAxisAngleRms), 3.0 * std::numbers::pi / 180.0);
  // Predictions 0.1 s ahead of an 8 mm p2p beat at 90 bpm: off by more than nothing, by
  // less than half the p2p.
  const double pred = Metric(res, metric::kPredictionRms);
  EXPECT_GT(pred, 0.05);
  EXPECT_LT(pred, kTargetP2pMm / 2.0);
  EXPECT_NEAR(Metric(res, metric::kPredictionTruthRms), pred, 0.6);  // detection noise apart
  // The loop follows the target at the standoff: its error stays below the p2p motion.
  EXPECT_LT(Metric(res, metric::kLoopRms), kTargetP2pMm);
  EXPECT_GT(Metric(res, metric::kLatencyP99), 0.0);
  EXPECT_EQ(res.metrics.count(metric::kEmRms), 0u);  // no EM log
  // The trace: every volume, and loop rows every 10 ms of the 3.1 s.
  ASSERT_EQ(trace.volumes.size(), static_cast<std::size_t>(kFrames));
  EXPECT_NEAR(static_cast<double>(trace.loop.size()), (kFrames - 1) / kRateHz / 0.01, 2.0);
  const auto following = std::count_if(trace.loop.begin(), trace.loop.end(),
                                       [](const TrialLoopRow& l) { return l.mode == "following"; });
  EXPECT_GT(following, 80);  // from ~2.1 s on
}

// Two settings of a detector, predictor, follower and servo parameter give different
// figures on the stage they act on.
TEST(TuneTrial, SettingsMatter) {
  ECHOSERVO_RELEASE_SUITE_ONLY("five replays of 32 volumes");
  auto run = [](std::vector<live::Assignment> extra, bool loop) {
    TrialRequest r = SimRequest();
    r.from_s = kFollowingFromS;
    r.loop = loop;
    for (auto& a : extra) r.settings.push_back(a);
    return RunTrial(r);
  };
  const TrialResult base = run({}, true);
  const TrialResult sheath = run({{"detector.sheath_diameter_mm", 1.5}}, false);
  EXPECT_NE(Metric(base, metric::kTipRms), Metric(sheath, metric::kTipRms));
  EXPECT_NE(Metric(base, metric::kAxisAngleRms), Metric(sheath, metric::kAxisAngleRms));
  // The predictor: the zero-order-hold baseline instead of the competition.
  const TrialResult hold = run({{"predictor.zero_order_hold", 1}}, false);
  EXPECT_NE(Metric(base, metric::kPredictionRms), Metric(hold, metric::kPredictionRms));
  EXPECT_EQ(Metric(base, metric::kTipRms), Metric(hold, metric::kTipRms));  // same detector
  // 4 mm more standoff: the tip is held 4 mm further back, and it is scored against the
  // target less the new standoff: the loop figure changes, by less than the 4 mm.
  const TrialResult standoff = run({{"follower.standoff_mm", 12.0}}, true);
  const double dl = Metric(standoff, metric::kLoopRms) - Metric(base, metric::kLoopRms);
  EXPECT_NE(dl, 0.0);
  EXPECT_LT(std::abs(dl), 4.0);
  const TrialResult gains = run({{"servo.kp_n_per_mm", 1.0}}, true);
  EXPECT_NE(Metric(gains, metric::kLoopRms), Metric(base, metric::kLoopRms));
  EXPECT_EQ(Metric(gains, metric::kPredictionRms), Metric(base, metric::kPredictionRms));
}

// The EM score goes through `echoservo report`'s alignment, which estimates the EM clock's
// offset from the tracked tip's motion. In these recordings the catheter stands still (only
// the annulus beats): a still tip carries no timing, so the alignment refuses, and the trial
// says so instead of giving a figure (a RUN of the demo, whose tip moves, gets one).
TEST(TuneTrial, EmLogNeedsAMovingTip) {
  ECHOSERVO_RELEASE_SUITE_ONLY("replays 32 volumes and aligns an EM log");
  const ::echoservo::testing::TempDir tmp("tune_trial_em");
  TrialRequest r = SimRequest();
  r.recording = MakeRun(tmp.path() / "RUN", 8.0).string();
  r.loop = false;
  const RecordingInfo info = InspectRecording(r.recording);
  EXPECT_TRUE(info.has_em);
  EXPECT_TRUE(info.has_truth);
  EXPECT_EQ(MetricUnavailableReason(info, metric::kEmRms), "");
  const TrialResult res = RunTrial(r);
  std::string notes;
  for (const std::string& n : res.notes) notes += n + "\n";
  SCOPED_TRACE(notes);
  EXPECT_EQ(res.metrics.count(metric::kEmRms), 0u);
  ExpectContains(notes, "em: not scored");
  ExpectContains(notes, "hardly moved");
  EXPECT_EQ(res.volumes, static_cast<std::size_t>(kFrames));  // the rest is scored
}

// A real PLUS sequence (2D frames, no truth): no detection metric against truth, the reason
// names the file; the replay runs and counts what the detector could not use.
TEST(TuneTrial, RealPlusSequenceWithoutTruth) {
  const std::string f = std::string(ECHOSERVO_DATA_DIR) + "/plus/SpinePhantomFreehand.igs.mha";
  const RecordingInfo info = InspectRecording(f);
  EXPECT_EQ(info.frames, 21u);
  EXPECT_FALSE(info.has_truth);
  EXPECT_FALSE(info.has_em);
  const std::string why = MetricUnavailableReason(info, metric::kTipRms);
  ExpectContains(why, "truth");
  ExpectContains(why, "SpinePhantomFreehand.igs.mha");
  ExpectContains(MetricUnavailableReason(info, metric::kEmRms), "EM log");
  EXPECT_EQ(MetricUnavailableReason(info, metric::kLatencyP50), "");
  ExpectContains(MetricUnavailableReason(info, "detection.nonsense"), "unknown metric");
  TrialRequest r;
  r.recording = f;
  r.from_s = 0.0;
  const TrialResult res = RunTrial(r);
  EXPECT_EQ(res.volumes + res.skipped, 21u);
  EXPECT_EQ(res.metrics.count(metric::kTipRms), 0u);
  EXPECT_EQ(res.metrics.count(metric::kPredictionTruthRms), 0u);
  EXPECT_LE(Metric(res, metric::kFoundFraction), 1.0);
  EXPECT_EQ(res.measured + (res.volumes - res.measured), res.volumes);
}

// The phantom source (a generator apart from the simulated scanner): its line and disc are
// drawn on a 0.5 mm grid with known truth.
TEST(TuneTrial, PhantomSource) {
  ECHOSERVO_RELEASE_SUITE_ONLY("a full search on three 80x74x104 volumes");
  TrialRequest r;
  r.recording = (Recordings() / kPhantomName).string();
  r.from_s = 0.0;
  r.loop = false;
  const TrialResult res = RunTrial(r);
  EXPECT_EQ(res.volumes, 3u);
  EXPECT_GE(Metric(res, metric::kFoundFraction), 0.0);
  // The drawn line is 3 voxels (1.5 mm) thick and ends at the truth's tip: the tip within
  // 2 voxel diagonals, the axis of a ~30 mm line within 3°.
  EXPECT_LT(Metric(res, metric::kTipRms), 2.0 * std::sqrt(3.0) * 0.5);
  EXPECT_LT(Metric(res, metric::kAxisAngleRms), 3.0 * std::numbers::pi / 180.0);
}

TEST(TuneTrial, BadInputIsNamed) {
  using ::echoservo::testing::InvalidArgumentMessage;
  TrialRequest r;
  r.recording = "/nonexistent/rec.igs.mha";
  ExpectContains(InvalidArgumentMessage([&] { RunTrial(r); }), "does not exist");
  ExpectContains(InvalidArgumentMessage([&] { InspectRecording(r.recording); }),
                 "/nonexistent/rec.igs.mha");
  r.recording = std::string(ECHOSERVO_DATA_DIR) +
                "/plus/WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha";
  ExpectContains(InvalidArgumentMessage([&] { RunTrial(r); }), "tracker-only sequence (no images)");
  r.recording = std::string(ECHOSERVO_DATA_DIR) + "/plus/SpinePhantomFreehandReconstructed.mha";
  ExpectContains(InvalidArgumentMessage([&] { RunTrial(r); }), "not a PLUS sequence");
  r.recording = std::string(ECHOSERVO_DATA_DIR) + "/plus/SpinePhantomFreehand.igs.mha";
  r.latency_s = 2.0;
  ExpectContains(InvalidArgumentMessage([&] { RunTrial(r); }), "latency_s");
  r.latency_s = 0.1;
  r.settings = {{"detector.sheath_diameter_mm", 99.0}};
  ExpectContains(InvalidArgumentMessage([&] { RunTrial(r); }), "detector.sheath_diameter_mm");
  r.settings = {{"detector.sheath_diamter_mm", 3.0}};
  ExpectContains(InvalidArgumentMessage([&] { RunTrial(r); }), "unknown parameter");
  r.settings = {};
  r.em_log = "/nonexistent/em.csv";
  ExpectContains(InvalidArgumentMessage([&] { RunTrial(r); }), "/nonexistent/em.csv");

  ExpectContains(InvalidArgumentMessage([] { RequestFromJson("{", "REQ"); }), "REQ");
  ExpectContains(InvalidArgumentMessage([] { RequestFromJson("{}", "REQ"); }), "recording");
  ExpectContains(InvalidArgumentMessage(
                     [] { RequestFromJson(R"({"recording": "a", "latncy_s": 1})", "REQ"); }),
                 "latncy_s");
  ExpectContains(InvalidArgumentMessage([] {
                   RequestFromJson(R"({"recording": "a", "settings": ["predictor.harmonics=99"]})",
                                   "REQ");
                 }),
                 "predictor.harmonics");
  ExpectContains(InvalidArgumentMessage(
                     [] { RequestFromJson(R"({"recording": "a", "from_s": "x"})", "REQ"); }),
                 "from_s");
}

TEST(TuneTrial, JsonRoundTrips) {
  TrialRequest r;
  r.recording = "/data/a.igs.mha";
  r.em_log = "/data/em.csv";
  r.settings = {{"detector.sheath_diameter_mm", 3.1}, {"predictor.harmonics", 4}};
  r.latency_s = 0.125;
  r.delay_s = 0.07;
  r.from_s = 1.5;
  r.seed = 17;
  r.loop = false;
  const TrialRequest b = RequestFromJson(RequestToJson(r), "req");
  EXPECT_EQ(b.recording, r.recording);
  EXPECT_EQ(b.em_log, r.em_log);
  EXPECT_EQ(b.settings, r.settings);
  EXPECT_EQ(b.latency_s, r.latency_s);
  EXPECT_EQ(b.delay_s, r.delay_s);
  EXPECT_EQ(b.from_s, r.from_s);
  EXPECT_EQ(b.seed, r.seed);
  EXPECT_EQ(b.loop, r.loop);
  TrialResult res;
  res.status = "failed";
  res.reason = "why";
  res.metrics = {{metric::kTipRms, 0.123456789012345}, {metric::kLoopRms, 2.5}};
  res.volumes = 9;
  res.measured = 7;
  res.errors = 1;
  res.skipped = 2;
  res.notes = {"n1"};
  const TrialResult c = ResultFromJson(ResultToJson(res), "res");
  EXPECT_EQ(c.status, res.status);
  EXPECT_EQ(c.reason, res.reason);
  EXPECT_EQ(c.metrics, res.metrics);
  EXPECT_EQ(c.volumes, 9u);
  EXPECT_EQ(c.measured, 7u);
  EXPECT_EQ(c.errors, 1u);
  EXPECT_EQ(c.skipped, 2u);
  EXPECT_EQ(c.notes, res.notes);
  ExpectContains(InvalidArgumentMessage([] { ResultFromJson(R"({"status": "maybe"})", "R"); }),
                 "status");
}

// `echoservo tune trial --request REQ --out RESULT`: always a RESULT, exit 0 or 2.
TEST(TuneTrial, TrialProcess) {
  ECHOSERVO_RELEASE_SUITE_ONLY("starts the echoservo program four times");
  const ::echoservo::testing::TempDir tmp("tune_trial_cli", true);
  const fs::path req = tmp.path() / "request.json", out = tmp.path() / "result.json";
  TrialRequest r;  // a real sequence, quick to replay (21 2D frames the detector refuses)
  r.recording = std::string(ECHOSERVO_DATA_DIR) + "/plus/SpinePhantomFreehand.igs.mha";
  r.from_s = 0.0;
  std::ofstream(req) << RequestToJson(r);
  const auto ok = RunCli("tune trial --request " + req.string() + " --out " + out.string());
  EXPECT_EQ(ok.rc, 0) << ok.err;
  const TrialResult good = ResultFromJson(::echoservo::testing::ReadFile(out), "result");
  EXPECT_EQ(good.status, "ok");
  EXPECT_EQ(good.volumes + good.skipped, 21u);
  // The same trial in this process counts the same (deterministic).
  const TrialResult here = RunTrial(r);
  EXPECT_EQ(good.measured, here.measured);
  EXPECT_EQ(good.errors, here.errors);
  EXPECT_EQ(good.metrics.at(metric::kFoundFraction), here.metrics.at(metric::kFoundFraction));

  r.settings = {{"detector.sheath_diameter_mm", 3.0}};
  std::string text = RequestToJson(r);
  text.replace(text.find("detector.sheath_diameter_mm=3"), 29, "detector.sheath_diameter_mm=77");
  std::ofstream(req) << text;
  const auto bad = RunCli("tune trial --request " + req.string() + " --out " + out.string());
  EXPECT_EQ(bad.rc, 2) << bad.err;
  const TrialResult failed = ResultFromJson(::echoservo::testing::ReadFile(out), "result");
  EXPECT_EQ(failed.status, "failed");
  ExpectContains(failed.reason, "detector.sheath_diameter_mm");

  fs::remove(req);
  const auto missing = RunCli("tune trial --request " + req.string() + " --out " + out.string());
  EXPECT_EQ(missing.rc, 2);
  ExpectContains(ResultFromJson(::echoservo::testing::ReadFile(out), "result").reason,
                 "cannot be read");

  const auto human = RunCli("tune trial --recording " + r.recording + " --from 0 --keep " +
                            (tmp.path() / "keep").string());
  EXPECT_EQ(human.rc, 0) << human.err;
  ExpectContains(human.out, metric::kFoundFraction);
  EXPECT_TRUE(fs::exists(tmp.path() / "keep" / "volumes.csv"));
  EXPECT_TRUE(fs::exists(tmp.path() / "keep" / "loop.csv"));
}

}  // namespace
}  // namespace echoservo::tune
