// The accuracy report (report/accuracy_report.h) on synthetic RUN directories whose
// tip is the target plus a constant offset d: the tip-to-target RMS, every beat's and every
// phase bin's RMS is |d| within the error that linear interpolation of the EM and truth
// tracks can make (a_max·h²/8 each); latency percentiles, dropped frames and drop-outs
// are those written; the JSON has the documented keys and the HTML is one self-contained
// page.
#include "report/accuracy_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "hw/io/em_log.h"
#include "hw/io/run_record.h"
#include "tests/test_util/browser.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/synthetic_run.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

using testing::ExpectContains;
using testing::InvalidArgumentMessage;
using testing::SyntheticRun;
using testing::TempDir;

struct Computed {
  hw::RunRecord run;
  report::AccuracyMetrics m;
};

Computed Compute(const SyntheticRun& s, const TempDir& dir) {
  testing::WriteSyntheticRun(s, dir.path());
  Computed c{hw::ReadRunRecord(dir.path()), {}};
  c.m = report::ComputeAccuracy(c.run, hw::ReadSimEmLog(c.run.EmPath(), {}));
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
  const hw::RunRecord run = hw::ReadRunRecord(dir.path());
  hw::EmLog em = hw::ReadSimEmLog(run.EmPath(), {});
  report::AccuracyOptions o;
  o.phase_bins = 0;
  ExpectContains(InvalidArgumentMessage([&] { report::ComputeAccuracy(run, em, o); }),
                 "phase_bins");
}

}  // namespace
}  // namespace echoservo
