// The RUN directory (formats/run_record.h): what RunWriter writes, ReadRunRecord reads back
// exactly; bad files and bad rows are errors naming the file, the line and the column.
#include "formats/run_record.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "formats/em_log.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"
#include "tests/test_util/trial_files.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using testing::ExpectContains;
using testing::InvalidArgumentMessage;
using testing::SetCsvField;
using testing::TempDir;
using testing::WriteLines;

formats::TargetRecord Target(double t, bool found) {
  formats::TargetRecord r;
  r.acquired_s = t;
  r.arrived_s = t + 0.011;
  r.published_s = t + 0.023;
  r.found = found;
  r.target_mm = {t, 2 * t, -t};
  r.tip_mm = {t + 1, 2 * t, -t};
  r.axis = {0, 0, 1};
  r.confidence = 0.9;
  return r;
}

// A small run: 20 volumes (one not found), servo, latency, EM and truth rows.
void WriteSmallRun(const fs::path& dir) {
  formats::RunInfo info;
  info.heart_rate_hz = 1.25;
  info.notes = "unit test";
  info.extra_json = R"({"operator": "test", "volume_rate_hz": 20})";
  info.meta.source = "unit test";
  info.meta.time_base = formats::RunTimeBase::kPipeline;
  info.meta.seed = 7;
  info.meta.duration_s = 1.0;
  info.meta.pipeline_to_unix_s = 1.7e9;
  info.meta.em_to_image = Eigen::Isometry3d(Eigen::Translation3d(1, 2, 3) *
                                            Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  info.meta.settings = {{"detector.sheath_diameter_mm", 2.5}, {"follower.offset_gain", 0.05}};
  formats::RunWriter w(dir, info);
  for (int i = 0; i < 20; ++i) {
    const double t = 0.05 * i;
    w.AddTarget(Target(t, i != 5));
    w.AddLatency({t + 0.011, t + 0.011 + 0.001 * (i + 1)});
    w.AddTruth({t, {t, 2 * t, -t}, {t + 1, 2 * t, -t}});
    w.AddEm({500.0 + t, {t, t, t}, i != 7});
  }
  for (int i = 0; i < 100; ++i) {
    w.AddServo(
        {0.001 * i, i < 50 ? "hold" : "track", 0.1 * i, 0.05 * i, 0.09 * i, i < 80 ? 0.0 : 1.0});
  }
}

TEST(RunRecord, WhatTheWriterWritesReadsBack) {
  const TempDir dir("run_record");
  WriteSmallRun(dir.path());
  const formats::RunRecord run = formats::ReadRunRecord(dir.path());
  ASSERT_TRUE(run.info.heart_rate_hz.has_value());
  EXPECT_EQ(*run.info.heart_rate_hz, 1.25);
  EXPECT_EQ(run.info.notes, "unit test");
  EXPECT_EQ(run.info.extra_json, R"({"operator":"test","volume_rate_hz":20})");
  EXPECT_TRUE(run.info.warnings.empty());
  const formats::RunMetadata& m = run.info.meta;
  EXPECT_EQ(m.source, "unit test");
  EXPECT_EQ(m.time_base, formats::RunTimeBase::kPipeline);
  EXPECT_EQ(m.seed, std::optional<std::uint64_t>(7));
  EXPECT_EQ(m.duration_s, std::optional<double>(1.0));
  EXPECT_EQ(m.pipeline_to_unix_s, std::optional<double>(1.7e9));
  ASSERT_TRUE(m.em_to_image.has_value());
  EXPECT_LT((m.em_to_image->translation() - Eigen::Vector3d(1, 2, 3)).norm(), 1e-8);
  EXPECT_NEAR(Eigen::AngleAxisd(m.em_to_image->rotation()).angle(), 0.5, 1e-8);
  ASSERT_EQ(m.settings.size(), 2u);
  EXPECT_EQ(m.settings[0].first, "detector.sheath_diameter_mm");
  EXPECT_EQ(m.settings[0].second, 2.5);
  ASSERT_EQ(run.targets.size(), 20u);
  for (std::size_t i = 0; i < run.targets.size(); ++i) {
    const formats::TargetRecord expected = Target(0.05 * static_cast<double>(i), i != 5);
    const formats::TargetRecord& r = run.targets[i];
    EXPECT_EQ(r.acquired_s, expected.acquired_s);  // shortest round-trip text: exact
    EXPECT_EQ(r.published_s, expected.published_s);
    EXPECT_EQ(r.found, expected.found);
    if (r.found) {
      EXPECT_EQ(r.tip_mm, expected.tip_mm);
      EXPECT_EQ(r.target_mm, expected.target_mm);
    } else {
      EXPECT_EQ(r.tip_mm, Eigen::Vector3d::Zero());
    }
  }
  EXPECT_TRUE(run.has_servo && run.has_latency && run.has_em && run.has_truth);
  ASSERT_EQ(run.servo.size(), 100u);
  EXPECT_EQ(run.servo[10].mode, "hold");
  EXPECT_EQ(run.servo[60].mode, "track");
  EXPECT_EQ(run.servo.back().faults, 1.0);
  ASSERT_EQ(run.latency.size(), 20u);
  EXPECT_EQ(run.truth.size(), 20u);
  const formats::EmLog em = formats::ReadSimEmLog(run.EmPath(), {});
  EXPECT_EQ(em.samples.size(), 20u);
  EXPECT_EQ(em.dropouts(), 1u);
  EXPECT_FALSE(em.samples[7].valid);
}

TEST(RunRecord, OptionalFilesMayBeAbsent) {
  const TempDir dir("run_minimal");
  {
    formats::RunWriter w(dir.path(), {});
    w.AddTarget(Target(0.0, true));
    w.AddTarget(Target(0.05, true));
  }
  const formats::RunRecord run = formats::ReadRunRecord(dir.path());
  EXPECT_FALSE(run.info.heart_rate_hz.has_value());
  EXPECT_FALSE(run.has_servo || run.has_latency || run.has_em || run.has_truth);
  EXPECT_EQ(run.targets.size(), 2u);
}

// timing.json as the demo writes it (live/servo_cycle_clock.h ServoTimingJson).
const char* kTimingJson = R"({"realtime": {"requested": true, "fifo": true, "priority": 80,
  "pinned": false, "cpu": null, "memory_locked": true, "refusals": [],
  "summary": "SCHED_FIFO 80, memory locked"},
 "timing": {"period_s": 0.001, "cycles": 8001, "overruns": 3, "overrun_fraction": 0.000375,
  "max_consecutive_overruns": 2,
  "wakeup_latency_us": {"p50": 52, "p99": 81, "p999": 140, "max": 812, "mean": 55, "count": 8001},
  "cycle_duration_us": {"p50": 20, "p99": 45, "p999": 90, "max": 1210, "mean": 22, "count": 8001}},
 "deadline": {"hold_after_overruns": 5, "retract_after_ms": 50, "resume_after_on_time": 200,
  "holds": 0, "retracts": 0}})";

TEST(RunRecord, TimingJsonReadsBackAndABadOneNamesTheKey) {
  const TempDir dir("run_record_timing");
  const fs::path run = dir.path() / "run";
  WriteSmallRun(run);
  EXPECT_FALSE(formats::ReadRunRecord(run).has_timing);
  WriteLines(run / "timing.json", {kTimingJson});
  const formats::RunRecord r = formats::ReadRunRecord(run);
  ASSERT_TRUE(r.has_timing);
  EXPECT_EQ(r.timing.realtime_summary, "SCHED_FIFO 80, memory locked");
  EXPECT_TRUE(r.timing.fifo);
  EXPECT_EQ(r.timing.cycles, 8001u);
  EXPECT_EQ(r.timing.overruns, 3u);
  EXPECT_EQ(r.timing.max_consecutive_overruns, 2u);
  EXPECT_DOUBLE_EQ(r.timing.wakeup_p99_us, 81.0);
  EXPECT_DOUBLE_EQ(r.timing.wakeup_max_us, 812.0);
  EXPECT_DOUBLE_EQ(r.timing.cycle_p999_us, 90.0);
  EXPECT_EQ(r.timing.deadline_holds, 0u);

  auto edited = [](const std::string& from, const std::string& to) {
    std::string t = kTimingJson;
    return t.replace(t.find(from), from.size(), to);
  };
  const std::pair<std::string, std::string> bad[] = {
      {"{", "timing.json: not valid JSON"},
      {"[]", "key 'realtime' must be an object"},
      {edited("\"overruns\": 3", "\"overruns\": 9999"),
       "'timing.overruns' exceeds 'timing.cycles'"},
      {edited("\"p99\": 81", "\"p99\": -1"), "'timing.wakeup_latency_us.p99' must be a number ≥ 0"},
      {edited("\"holds\": 0", "\"holds\": \"x\""), "'deadline.holds' must be a count"},
  };
  for (const auto& [text, why] : bad) {
    WriteLines(run / "timing.json", {text});
    ExpectContains(InvalidArgumentMessage([&] { formats::ReadRunRecord(run); }), why);
  }
}

// tracker.json: the writer's text reads back; a missing or bad count, or counts that cannot
// hold together, name the file and the key.
TEST(RunRecord, TrackerCountsReadBackAndBadOnesNameTheKey) {
  const TempDir dir("run_record_tracker");
  const fs::path run = dir.path() / "run";
  WriteSmallRun(run);
  EXPECT_FALSE(formats::ReadRunRecord(run).has_tracker_counts);
  formats::TrackerVolumeCounts c;
  c.acquired = 500;
  c.missed = 3;
  c.shed = 12;
  c.processed = 488;
  c.not_found = 7;
  WriteLines(run / "tracker.json", {formats::TrackerCountsJson(c)});
  const formats::RunRecord r = formats::ReadRunRecord(run);
  ASSERT_TRUE(r.has_tracker_counts);
  EXPECT_EQ(r.tracker.acquired, 500u);
  EXPECT_EQ(r.tracker.missed, 3u);
  EXPECT_EQ(r.tracker.shed, 12u);
  EXPECT_EQ(r.tracker.skipped, 0u);
  EXPECT_EQ(r.tracker.processed, 488u);
  EXPECT_EQ(r.tracker.not_found, 7u);
  const std::pair<std::string, std::string> bad[] = {
      {"{", "tracker.json: not valid JSON"},
      {"[]", "must be a JSON object"},
      {R"({"acquired": 5, "missed": 0, "shed": 0, "skipped": 0, "processed": 5})",
       "key 'not_found' must be a count"},
      {R"({"acquired": 5, "missed": -1, "shed": 0, "skipped": 0, "processed": 5, "not_found": 0})",
       "key 'missed' must be a count"},
      {R"({"acquired": 5, "missed": 0, "shed": 0, "skipped": 0, "processed": 6, "not_found": 0})",
       "cannot exceed 'acquired'"},
      {R"({"acquired": 5, "missed": 0, "shed": 0, "skipped": 0, "processed": 5, "not_found": 6})",
       "'not_found' exceeds 'processed'"},
  };
  for (const auto& [text, why] : bad) {
    WriteLines(run / "tracker.json", {text});
    ExpectContains(InvalidArgumentMessage([&] { formats::ReadRunRecord(run); }), why);
  }
}

TEST(RunRecord, WriterRejectsBadRows) {
  const TempDir dir("run_writer");
  formats::RunWriter w(dir.path(), {});
  w.AddTarget(Target(1.0, true));
  ExpectContains(InvalidArgumentMessage([&] { w.AddTarget(Target(1.0, true)); }),
                 "targets.csv: time 1 s is not after the previous row's 1 s");
  formats::TargetRecord nan = Target(2.0, true);
  nan.tip_mm.x() = std::numeric_limits<double>::quiet_NaN();
  ExpectContains(InvalidArgumentMessage([&] { w.AddTarget(nan); }),
                 "column 'tip_mm': the value is not finite");
  ExpectContains(InvalidArgumentMessage([&] {
                   w.AddServo({0.0, "a,b", 0, 0, 0, 0});
                 }),
                 "column 'mode'");
  ExpectContains(InvalidArgumentMessage([&] {
                   w.AddLatency({1.0, 0.5});
                 }),
                 "applied_s is before arrived_s");
  ExpectContains(InvalidArgumentMessage([&] { formats::RunWriter again(dir.path(), {}); }),
                 "run.json: already exists");
}

TEST(RunRecord, BadFilesNameTheFileLineAndColumn) {
  const TempDir dir("run_bad");
  ExpectContains(InvalidArgumentMessage([&] { formats::ReadRunRecord(dir.path()); }),
                 "no such folder");
  WriteSmallRun(dir.path());
  const fs::path json = dir.path() / "run.json";
  const fs::path targets = dir.path() / "targets.csv";
  const std::string good_json = [&] {
    std::ifstream in(json);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  auto expect_json_error = [&](const std::string& text, const std::string& part) {
    std::ofstream(json, std::ios::trunc) << text;
    const std::string msg = InvalidArgumentMessage([&] { formats::ReadRunRecord(dir.path()); });
    ExpectContains(msg, json.string());
    ExpectContains(msg, part);
  };
  expect_json_error(R"({"format": "trial", "version": 1})",
                    "key 'format' must be \"echoservo-run\"");
  expect_json_error(R"({"format": "echoservo-run", "version": 2})",
                    "key 'version': 2 is not a version");
  expect_json_error(R"({"format": "echoservo-run", "version": 1, "heart_rate_hz": 20})",
                    "key 'heart_rate_hz': 20 is not a number in (0, 10] Hz");
  expect_json_error("{\"format\": ", "not valid JSON");
  // The typed metadata: a wrong type or value names the key.
  const std::string head = R"({"format": "echoservo-run", "version": 1, )";
  expect_json_error(head + R"("time_base": 3})", "key 'time_base' must be a string");
  expect_json_error(head + R"("time_base": "gps"})",
                    "key 'time_base': 'gps' is not one of pipeline, unix, recording");
  expect_json_error(head + R"("em_to_image": "1,0,0,0, 0,1,0,0"})",
                    "key 'em_to_image': expected 12 or 16 numbers");
  expect_json_error(head + R"("em_to_image": "2,0,0,0, 0,1,0,0, 0,0,1,0"})",
                    "key 'em_to_image': not a rigid transform");
  expect_json_error(head + R"("em_to_image": 5})", "key 'em_to_image' must be a string");
  expect_json_error(head + R"("seed": -1})", "key 'seed': -1 is not a non-negative integer");
  expect_json_error(head + R"("duration_s": "long"})", "key 'duration_s'");
  expect_json_error(head + R"("settings": {"follower.offset_gain": "a"}})",
                    "key 'settings': 'follower.offset_gain'");
  std::ofstream(json, std::ios::trunc) << good_json;

  SetCsvField(targets, 4, 3, "2");
  std::string msg = InvalidArgumentMessage([&] { formats::ReadRunRecord(dir.path()); });
  ExpectContains(msg, targets.string() + ": line 4: column 'found': 2 is not 0 or 1");
  SetCsvField(targets, 4, 3, "1");
  SetCsvField(targets, 6, 1, "0.1");  // arrived before acquired (0.2)
  msg = InvalidArgumentMessage([&] { formats::ReadRunRecord(dir.path()); });
  ExpectContains(msg, ": line 6: column 'arrived_s': 0.1 s is before acquired_s = 0.2 s");
  SetCsvField(targets, 6, 1, "0.211");
  SetCsvField(targets, 7, 0, "0.2");
  msg = InvalidArgumentMessage([&] { formats::ReadRunRecord(dir.path()); });
  ExpectContains(msg, ": line 7: column 'acquired_s': times must be strictly increasing");
  WriteLines(targets, {"acquired_s,arrived_s", "0,0"});
  msg = InvalidArgumentMessage([&] { formats::ReadRunRecord(dir.path()); });
  ExpectContains(msg, "missing required columns");
  ExpectContains(msg, "(header: acquired_s,arrived_s,published_s,found,");
  fs::remove(targets);
  ExpectContains(InvalidArgumentMessage([&] { formats::ReadRunRecord(dir.path()); }),
                 "targets.csv: not found");
}

// A RUN written before the typed metadata (no source, no time_base) reads as before, with a
// warning naming the file and the key; its other keys are kept.
TEST(RunRecord, AnOlderRunWithoutTypedMetadataReadsWithAWarning) {
  const TempDir dir("run_old");
  WriteSmallRun(dir.path());
  std::ofstream(dir.path() / "run.json", std::ios::trunc)
      << R"({"format": "echoservo-run", "version": 1, "heart_rate_hz": 1.25, "operator": "x"})";
  const formats::RunRecord run = formats::ReadRunRecord(dir.path());
  EXPECT_EQ(run.info.meta.time_base, formats::RunTimeBase::kUnstated);
  EXPECT_FALSE(run.info.meta.em_to_image.has_value());
  EXPECT_EQ(run.info.extra_json, R"({"operator":"x"})");
  ASSERT_EQ(run.info.warnings.size(), 2u);
  ExpectContains(run.info.warnings[0], "run.json: no 'source'");
  ExpectContains(run.info.warnings[1], "run.json: no 'time_base'");
}

// The writer refuses a typed key smuggled in as an untyped one.
TEST(RunWriter, ATypedKeyInTheExtraKeysIsRefused) {
  const TempDir dir("run_extra");
  formats::RunInfo info;
  info.extra_json = R"({"em_to_image": "1,0,0,0, 0,1,0,0, 0,0,1,0"})";
  ExpectContains(InvalidArgumentMessage([&] { formats::RunWriter w(dir.path() / "r", info); }),
                 "key 'em_to_image' is typed");
}

// kill -9 while writing: every row added before the kill is on disk and the RUN directory
// reads back whole (nothing lost but the row in flight; here none is in flight).
TEST(RunWriter, AProcessKilledWhileWritingLosesNoRowAlreadyAdded) {
  const TempDir dir("run_kill9", true);
  const fs::path run = dir.path() / "run";
  constexpr int kRows = 137;
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {  // the writer: adds its rows, says so, then waits to be killed
    ::close(ready[0]);
    formats::RunWriter w(run, {});
    for (int i = 0; i < kRows; ++i) {
      const double t = 0.04 * i;
      w.AddTarget({t, t + 0.05, t + 0.06, true, Eigen::Vector3d(1, 2, 3 + 0.01 * i),
                   Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, 1), 0.9});
      w.AddServo({t, "following", 0.1 * i, 0.2, 0.3, 0});
      w.AddLatency({t + 0.05, t + 0.055});
    }
    const char byte = 1;
    if (::write(ready[1], &byte, 1) != 1) ::_exit(2);
    for (;;) ::pause();
  }
  ::close(ready[1]);
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);
  ::close(ready[0]);
  ASSERT_EQ(::kill(child, SIGKILL), 0);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));
  const formats::RunRecord r = formats::ReadRunRecord(run);
  ASSERT_EQ(r.targets.size(), static_cast<std::size_t>(kRows));
  ASSERT_EQ(r.servo.size(), static_cast<std::size_t>(kRows));
  ASSERT_EQ(r.latency.size(), static_cast<std::size_t>(kRows));
  EXPECT_DOUBLE_EQ(r.targets.back().target_mm.z(), 3 + 0.01 * (kRows - 1));
  EXPECT_DOUBLE_EQ(r.servo.back().setpoint_mm, 0.1 * (kRows - 1));
}

}  // namespace
}  // namespace echoservo
