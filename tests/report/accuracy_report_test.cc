// The accuracy report (report/accuracy_report.h) on synthetic RUN directories whose
// tip is the target plus a constant offset d: the tip-to-target RMS, every beat's and every
// phase bin's RMS is |d| within the error that linear interpolation of the EM and truth
// tracks can make (a_max·h²/8 each); latency percentiles, dropped frames and drop-outs
// are those written; the JSON has the documented keys and the HTML is one self-contained
// page.
#include "report/accuracy_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "formats/em_log.h"
#include "formats/run_record.h"
#include "tests/test_util/browser.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/synthetic_run.h"
#include "tests/test_util/temp_dir.h"
#include "tests/test_util/trial_files.h"

namespace echoservo {
namespace {

using testing::ExpectContains;
using testing::InvalidArgumentMessage;
using testing::SyntheticRun;
using testing::TempDir;

struct Computed {
  formats::RunRecord run;
  report::AccuracyMetrics m;
};

Computed Compute(const SyntheticRun& s, const TempDir& dir) {
  testing::WriteSyntheticRun(s, dir.path());
  Computed c{formats::ReadRunRecord(dir.path()), {}};
  c.m = report::ComputeAccuracy(c.run, formats::ReadSimEmLog(c.run.EmPath(), {}));
  return c;
}

// |error − |d|| is at most the interpolation error of the EM track at the image times (the
// registration's bias) plus that of the target track at the EM times.
double InterpolationBoundMm(const SyntheticRun& s, double target_rate_hz) {
  const double a = s.MaxAccelerationMmS2();
  const double h_em = 1.0 / s.em_rate_hz, h_target = 1.0 / target_rate_hz;
  return 2.0 * a * h_em * h_em / 8.0 + a * h_target * h_target / 8.0;
}

TEST(AccuracyReport, ConstantTipOffsetGivesThatRmsEverywhere) {
  SyntheticRun s;
  s.not_found = {10, 11, 50};
  s.gap_from = 100, s.gap_to = 103;
  s.em_dropout_every = 13;
  const TempDir dir("accuracy_report");
  const Computed c = Compute(s, dir);
  const report::AccuracyMetrics& m = c.m;
  const double d = s.tip_offset_mm.norm();
  const double tol = InterpolationBoundMm(s, s.truth_rate_hz);
  EXPECT_EQ(m.target_source, "truth.csv");
  EXPECT_NEAR(m.rms_mm, d, tol);
  EXPECT_NEAR(m.mean_mm, d, tol);
  EXPECT_NEAR(m.max_mm, d, 2 * tol);
  EXPECT_NEAR(m.alignment.em_time_offset_s, s.em_clock_offset_s, 1e-3);
  // Per beat: a 1.2 Hz heartbeat over 20 s, from run.json.
  EXPECT_EQ(m.heart_rate_source, "run.json");
  EXPECT_DOUBLE_EQ(m.heart_rate_hz, s.heart_rate_hz);
  const double beats = s.duration_s * s.heart_rate_hz;
  EXPECT_GE(static_cast<double>(m.beats.size()), std::floor(beats));
  EXPECT_LE(static_cast<double>(m.beats.size()), std::ceil(beats) + 1);
  for (const auto& b : m.beats) EXPECT_NEAR(b.rms_mm, d, tol) << "beat at " << b.start_s;
  ASSERT_EQ(m.phase_rms_mm.size(), 10u);
  for (std::size_t i = 0; i < 10; ++i) {
    EXPECT_NEAR(m.phase_rms_mm[i], d, tol) << "phase bin " << i;
    // Uniform sampling in time fills the bins evenly (within one beat's samples).
    EXPECT_NEAR(static_cast<double>(m.phase_samples[i]),
                static_cast<double>(m.error_mm.size()) / 10.0,
                s.em_rate_hz / s.heart_rate_hz / 10.0 + 2);
  }
  // Latency rows i = 0..99 hold (i + 1) ms: linear-interpolation percentiles of 1..100.
  EXPECT_EQ(m.latency.count, 100u);
  EXPECT_NEAR(m.latency.p50_ms, 50.5, 1e-6);
  EXPECT_NEAR(m.latency.p95_ms, 95.05, 1e-6);
  EXPECT_NEAR(m.latency.p99_ms, 99.01, 1e-6);
  EXPECT_NEAR(m.latency.max_ms, 100.0, 1e-6);
  EXPECT_NEAR(m.pipeline.p50_ms, 42.0, 1e-6);
  // Dropped: 3 not found, 3 volumes in the gap.
  EXPECT_EQ(m.dropped.not_found, 3u);
  EXPECT_EQ(m.dropped.gaps, 1u);
  EXPECT_EQ(m.dropped.missing_in_gaps, 3u);
  EXPECT_EQ(m.dropped.total(), 6u);
  // EM drop-outs as written.
  std::size_t missing = 0;
  for (const auto& e : s.EmSamples()) missing += e.valid ? 0 : 1;
  EXPECT_EQ(m.em.dropouts(), missing);
  // Servo: 2 s of hold, the rest tracking.
  EXPECT_NEAR(m.servo_mode_s.at("hold"), 2.0, 1e-9);
}

TEST(AccuracyReport, WithoutTruthOrHeartRateUsesTheTrackedTargetAndItsPeriod) {
  SyntheticRun s;
  s.write_truth = false;
  s.write_heart_rate = false;
  const TempDir dir("accuracy_tracked");
  const Computed c = Compute(s, dir);
  EXPECT_EQ(c.m.target_source, "targets.csv");
  EXPECT_NEAR(c.m.rms_mm, s.tip_offset_mm.norm(), InterpolationBoundMm(s, s.volume_rate_hz));
  EXPECT_EQ(c.m.heart_rate_source, "target motion");
  EXPECT_NEAR(c.m.heart_rate_hz, s.heart_rate_hz, 0.01 * s.heart_rate_hz);
  EXPECT_FALSE(c.m.beats.empty());
}

TEST(AccuracyReport, JsonHasTheDocumentedKeys) {
  SyntheticRun s;
  s.duration_s = 10.0;
  const TempDir dir("accuracy_json");
  const Computed c = Compute(s, dir);
  report::AccuracyReportOptions o;
  o.run_path = dir.str();
  o.em_path = c.run.EmPath().string();
  const auto j = nlohmann::json::parse(report::AccuracyJson(c.m, o));
  for (const char* key :
       {"tip_to_target_rms_mm", "per_beat_rms_mm", "phase_rms_mm", "latency_ms", "dropped_frames",
        "em_time_offset_s", "registration_rms_mm", "em_samples", "em_dropouts", "em_to_image"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  for (const char* key : {"p50", "p95", "p99", "max"}) EXPECT_TRUE(j["latency_ms"].contains(key));
  EXPECT_EQ(j["per_beat_rms_mm"].size(), c.m.beats.size());
  EXPECT_EQ(j["phase_rms_mm"].size(), 10u);
  EXPECT_DOUBLE_EQ(j["tip_to_target_rms_mm"].get<double>(), c.m.rms_mm);
  EXPECT_EQ(j["em_samples"].get<std::size_t>(), s.EmSamples().size());
}

TEST(AccuracyReport, HtmlIsOneSelfContainedPageWithTheFigures) {
  SyntheticRun s;
  s.duration_s = 10.0;
  s.not_found = {4};
  const TempDir dir("accuracy_html");
  const Computed c = Compute(s, dir);
  report::AccuracyReportOptions o;
  o.run_path = "runs/<odd> & \"name\"";
  o.em_path = "em.csv";
  o.generated = "2024-01-01 00:00 UTC";
  const std::string html = report::RenderAccuracyReport(c.run, c.m, o);
  testing::browser::ExpectSelfContainedPage(html);
  for (const char* id :
       {"summary", "error", "beats", "latency", "alignment", "em", "frames", "servo"}) {
    EXPECT_NE(html.find(std::string("<section id=\"") + id + "\">"), std::string::npos) << id;
  }
  for (const char* title :
       {"Tip-to-target error", "Tip-to-target RMS per beat", "Tip-to-target RMS by heartbeat phase",
        "Latency distribution", "Coarse search: registration RMS by clock offset", "Servo"}) {
    EXPECT_NE(html.find(std::string("aria-label=\"") + title), std::string::npos) << title;
  }
  EXPECT_NE(html.find("runs/&lt;odd&gt; &amp; &quot;name&quot;"), std::string::npos);
  EXPECT_EQ(html.find("<odd>"), std::string::npos);
  char rms[32];
  std::snprintf(rms, sizeof rms, "%.3f mm", c.m.rms_mm);
  EXPECT_NE(html.find(rms), std::string::npos);
}

// ---------------------------------------------------------------- plausibility checks
// An EM log that does not belong to the run is refused, estimated or given transform, with
// the reason and the numbers; options.force gives the figures with the warnings.

formats::EmLog EmOf(const SyntheticRun& s, const TempDir& dir) {
  testing::WriteSyntheticRun(s, dir.path());
  return formats::ReadSimEmLog(dir.path() / "em.csv", {});
}

report::AccuracyOptions GivenTransform(const SyntheticRun& s) {
  report::AccuracyOptions o;
  o.alignment.em_to_image = s.em_to_image;
  o.transform_source = "run.json";
  return o;
}

TEST(AccuracyChecks, TheRightLogPassesEveryCheck) {
  SyntheticRun s;
  s.duration_s = 10.0;
  s.em_noise_mm = 0.3;
  s.image_noise_mm = 0.3;
  const TempDir dir("checks_right");
  const Computed c = Compute(s, dir);
  ASSERT_EQ(c.m.checks.size(), 4u);
  for (const auto& check : c.m.checks) EXPECT_TRUE(check.passed) << check.message;
  EXPECT_FALSE(c.m.forced);
  EXPECT_TRUE(c.m.warnings.empty());
  EXPECT_EQ(c.m.transform_source, "estimated");
  // Registration RMS ≈ √3·√(σ_em² + σ_image²) = 0.73 mm, well under 2.4 mm.
  EXPECT_LT(c.m.checks[0].value, 1.0);
  // Motion SD ≥ 4 mm along the principal axis against ≈ 0.42 mm of noise per axis.
  EXPECT_GT(c.m.checks[2].value, 0.99);
  EXPECT_GT(c.m.checks[3].value, 0.99);
  // Given the true transform: the same figure, the source named.
  const report::AccuracyMetrics g =
      report::ComputeAccuracy(c.run, formats::ReadSimEmLog(c.run.EmPath(), {}), GivenTransform(s));
  EXPECT_EQ(g.transform_source, "run.json");
  EXPECT_NEAR(g.rms_mm, c.m.rms_mm, 0.02);
}

TEST(AccuracyChecks, AnotherMotionsLogIsRefusedWithAGivenTransform) {
  SyntheticRun s;
  s.duration_s = 10.0;
  const TempDir dir("checks_other"), other_dir("checks_other_em");
  testing::WriteSyntheticRun(s, dir.path());
  const formats::RunRecord run = formats::ReadRunRecord(dir.path());
  SyntheticRun other = s;  // another heartbeat, another breath, same frame and clock
  other.heart_rate_hz = 1.55;
  other.breathing_hz = 0.31;
  other.amplitude_mm = {7.0, 9.0, 3.0};
  const formats::EmLog em = EmOf(other, other_dir);
  const std::string why =
      InvalidArgumentMessage([&] { report::ComputeAccuracy(run, em, GivenTransform(s)); });
  ExpectContains(why, "EM log refused");
  ExpectContains(why, "exceeds the 2.40 mm bound (EM tracker 1.40 mm + detector 1.00 mm)");
  ExpectContains(why, "--force");
  // Estimated, too.
  EXPECT_THROW(report::ComputeAccuracy(run, em), std::invalid_argument);
  // Forced: the figures, marked.
  report::AccuracyOptions o = GivenTransform(s);
  o.force = true;
  const report::AccuracyMetrics m = report::ComputeAccuracy(run, em, o);
  EXPECT_TRUE(m.forced);
  ASSERT_FALSE(m.warnings.empty());
  EXPECT_GT(m.rms_mm, 2.4);
  report::AccuracyReportOptions ro;
  const auto j = nlohmann::json::parse(report::AccuracyJson(m, ro));
  EXPECT_TRUE(j["forced"].get<bool>());
  EXPECT_EQ(j["warnings"].size(), m.warnings.size());
  EXPECT_EQ(j["em_to_image_source"], "run.json");
  const std::string html = report::RenderAccuracyReport(run, m, ro);
  EXPECT_NE(html.find("id=\"forced\""), std::string::npos);
  EXPECT_NE(html.find("Warning: figures forced (--force)"), std::string::npos);
}

TEST(AccuracyChecks, AStillSensorIsRefusedWithAGivenTransform) {
  SyntheticRun s;
  s.duration_s = 10.0;
  const TempDir dir("checks_still"), still_dir("checks_still_em");
  testing::WriteSyntheticRun(s, dir.path());
  const formats::RunRecord run = formats::ReadRunRecord(dir.path());
  SyntheticRun still = s;
  still.amplitude_mm = Eigen::Vector3d::Zero();
  still.em_noise_mm = 0.02;  // the bench sensors' jitter (docs/report.md)
  const std::string why = InvalidArgumentMessage(
      [&] { report::ComputeAccuracy(run, EmOf(still, still_dir), GivenTransform(s)); });
  ExpectContains(why, "the EM sensor's motion does not follow the tracked tip's: correlation");
  ExpectContains(why, "registration RMS");
}

TEST(AccuracyChecks, ALogThatStartedLateIsRefused) {
  // The EM recording started 2.1 s after the first volume, so "both started together" puts
  // the search window (± 1.5 s) 2.1 s from the true offset: its best offset is an alias one
  // beat from the truth, where the breathing (0.23 Hz) no longer matches (3.3 mm RMS). A
  // shift by whole beats and breaths (5 beats ≈ 0.96 breaths = 4.17 s) cannot be told from
  // the truth by any check: a periodic motion aliases.
  SyntheticRun s;
  s.duration_s = 16.0;
  const TempDir dir("checks_late"), late_dir("checks_late_em");
  testing::WriteSyntheticRun(s, dir.path());
  const formats::RunRecord run = formats::ReadRunRecord(dir.path());
  SyntheticRun late = s;
  late.em_lead_s = -2.1;         // from t = 2.1 s
  late.duration_s = 16.0 + 2.1;  // to the end of the run (16 s)
  const formats::EmLog em = EmOf(late, late_dir);
  report::AccuracyOptions narrow = GivenTransform(s);
  narrow.alignment.max_offset_s = 1.5;
  const std::string why = InvalidArgumentMessage([&] { report::ComputeAccuracy(run, em, narrow); });
  ExpectContains(why, "EM log refused");
  ExpectContains(why, "exceeds the 2.40 mm bound");
  // With the right centre it is the right log.
  report::AccuracyOptions o = GivenTransform(s);
  o.alignment.offset_center_s = s.em_clock_offset_s;
  const report::AccuracyMetrics m = report::ComputeAccuracy(run, em, o);
  EXPECT_NEAR(m.alignment.em_time_offset_s, s.em_clock_offset_s, 1e-3);
  EXPECT_NEAR(m.rms_mm, s.tip_offset_mm.norm(), InterpolationBoundMm(s, s.truth_rate_hz));
}

TEST(AccuracyChecks, AnOffsetOnTheEdgeOfTheSearchWindowFails) {
  SyntheticRun s;
  s.duration_s = 6.0;
  const TempDir dir("checks_edge");
  testing::WriteSyntheticRun(s, dir.path());
  const formats::RunRecord run = formats::ReadRunRecord(dir.path());
  const report::PointSeries em = report::ValidEmPoints(formats::ReadSimEmLog(run.EmPath(), {}));
  report::PointSeries tip;
  for (const auto& r : run.targets) tip.Add(r.acquired_s, r.tip_mm);
  report::EmAlignment a = report::AlignEmToImage(em, tip);
  for (const auto& c : report::CheckAlignment(em, tip, a)) EXPECT_TRUE(c.passed) << c.message;
  // The same pose and offset, but a window whose edge the offset sits on.
  a.offset_center_s = a.em_time_offset_s - a.max_offset_s;
  const auto checks = report::CheckAlignment(em, tip, a);
  ASSERT_EQ(checks[1].name, "clock offset");
  EXPECT_FALSE(checks[1].passed);
  ExpectContains(checks[1].message, "lies at the edge of the search window");
  ExpectContains(checks[1].message, "widen --max-offset or set --offset-center");
  for (std::size_t i : {0u, 2u, 3u}) EXPECT_TRUE(checks[i].passed) << checks[i].message;
}

TEST(AccuracyWindow, StartsWhenTheServoBeganFollowingUnlessFromIsGiven) {
  SyntheticRun s;
  s.duration_s = 10.0;
  const TempDir dir("window");
  testing::WriteSyntheticRun(s, dir.path());
  const formats::EmLog em = formats::ReadSimEmLog(dir.path() / "em.csv", {});
  // The synthetic servo.csv's modes are "hold" then "track": no following row.
  report::AccuracyMetrics m = report::ComputeAccuracy(formats::ReadRunRecord(dir.path()), em);
  EXPECT_FALSE(std::isfinite(m.window_from_s));
  EXPECT_EQ(report::WindowText(m), "whole run: servo.csv has no 'following' row");
  // The servo's own label (control/target_follower.cc): following from row 20, t = 2 s.
  std::vector<std::string> lines = testing::ReadLines(dir.path() / "servo.csv");
  for (auto& line : lines) {
    const auto at = line.find(",track,");
    if (at != std::string::npos) line.replace(at, 7, ",following,");
  }
  testing::WriteLines(dir.path() / "servo.csv", lines);
  m = report::ComputeAccuracy(formats::ReadRunRecord(dir.path()), em);
  // Plus the settling time (report/scored_window.h): two beats at run.json's 72 bpm is 1.67 s,
  // below the 2 s floor.
  EXPECT_DOUBLE_EQ(m.window_from_s, 4.0);
  EXPECT_EQ(report::WindowText(m),
            "from 4.00 s: servo began following at 2.00 s + settling 2.00 s (2 beats at 72.0 bpm, "
            "at least 2.0 s)");
  EXPECT_GE(m.t_s.front(), 4.0);
  EXPECT_LT(m.t_s.front(), 4.0 + 2.0 / s.em_rate_hz);
  report::AccuracyOptions o;
  o.from_s = 4.0;
  m = report::ComputeAccuracy(formats::ReadRunRecord(dir.path()), em, o);
  EXPECT_EQ(report::WindowText(m), "from 4.00 s: --from");
  EXPECT_GE(m.t_s.front(), 4.0);
  const auto j = nlohmann::json::parse(report::AccuracyJson(m, {}));
  EXPECT_DOUBLE_EQ(j["window"]["from_s"].get<double>(), 4.0);
  EXPECT_EQ(j["window"]["reason"], "--from");
  // No servo.csv: the whole run.
  std::filesystem::remove(dir.path() / "servo.csv");
  m = report::ComputeAccuracy(formats::ReadRunRecord(dir.path()), em);
  EXPECT_EQ(report::WindowText(m), "whole run: no servo.csv");
}

TEST(AccuracyReport, PercentileInterpolatesBetweenOrderStatistics) {
  EXPECT_DOUBLE_EQ(report::Percentile({3, 1, 2, 4}, 0.5), 2.5);
  EXPECT_DOUBLE_EQ(report::Percentile({5}, 0.99), 5.0);
  EXPECT_TRUE(std::isnan(report::Percentile({}, 0.5)));
}

TEST(AccuracyReport, RejectsBadOptions) {
  SyntheticRun s;
  s.duration_s = 6.0;
  const TempDir dir("accuracy_overlap");
  testing::WriteSyntheticRun(s, dir.path());
  const formats::RunRecord run = formats::ReadRunRecord(dir.path());
  formats::EmLog em = formats::ReadSimEmLog(run.EmPath(), {});
  report::AccuracyOptions o;
  o.phase_bins = 0;
  ExpectContains(InvalidArgumentMessage([&] { report::ComputeAccuracy(run, em, o); }),
                 "phase_bins");
}

// report --tracker-lag: a given lag (PLUS's sign, t_image = t_EM − lag) is used as the clock
// offset, not searched; the report says which lag and where it came from.
TEST(AccuracyReport, AGivenTrackerLagIsUsedNotSearched) {
  SyntheticRun s;
  s.duration_s = 10.0;
  const TempDir dir("accuracy_tracker_lag");
  testing::WriteSyntheticRun(s, dir.path());
  const formats::RunRecord run = formats::ReadRunRecord(dir.path());
  const formats::EmLog em = formats::ReadSimEmLog(run.EmPath(), {});
  const double d = s.tip_offset_mm.norm();
  report::AccuracyOptions o;
  o.alignment.fixed_offset_s = s.em_clock_offset_s;  // the true lag is −em_clock_offset_s
  o.tracker_lag_s = -s.em_clock_offset_s;
  o.offset_source = "--tracker-lag given";
  const report::AccuracyMetrics m = report::ComputeAccuracy(run, em, o);
  EXPECT_TRUE(m.alignment.fixed_offset);
  EXPECT_DOUBLE_EQ(m.alignment.em_time_offset_s, s.em_clock_offset_s);  // exactly, not refined
  EXPECT_EQ(m.alignment.grid_offset_s.size(), 1u);
  EXPECT_NEAR(m.rms_mm, d, InterpolationBoundMm(s, s.truth_rate_hz));
  report::AccuracyReportOptions ro;
  ro.run_path = dir.str();
  const auto j = nlohmann::json::parse(report::AccuracyJson(m, ro));
  EXPECT_EQ(j["em_time_offset_source"], "--tracker-lag given");
  EXPECT_DOUBLE_EQ(j["tracker_lag_s"].get<double>(), -s.em_clock_offset_s);
  ExpectContains(report::RenderAccuracyReport(run, m, ro), "--tracker-lag given");
  // A lag 40 ms off is kept as given (the estimate would have found the true offset): the
  // tip moves up to v_max · 40 ms against the target, so the error grows.
  o.alignment.fixed_offset_s = s.em_clock_offset_s + 0.04;
  o.force = true;
  const report::AccuracyMetrics off = report::ComputeAccuracy(run, em, o);
  EXPECT_DOUBLE_EQ(off.alignment.em_time_offset_s, s.em_clock_offset_s + 0.04);
  EXPECT_GT(off.rms_mm, m.rms_mm + 0.1);
  // Without a lag the offset is estimated, and the JSON says so.
  const report::AccuracyMetrics estimated = report::ComputeAccuracy(run, em);
  EXPECT_FALSE(estimated.alignment.fixed_offset);
  EXPECT_EQ(estimated.offset_source, "estimated");
  EXPECT_TRUE(
      nlohmann::json::parse(report::AccuracyJson(estimated, ro))["tracker_lag_s"].is_null());
}

}  // namespace
}  // namespace echoservo
