// Accuracy of a tracking run (`echoservo report RUN`): how far the catheter tip, as the EM
// tracker measured it, was from the target, and what the pipeline's timing was.
//
// In: a RUN directory (formats/run_record.h) and an EM-tracker log (formats/em_log.h), aligned
// to the image by report/em_alignment.h. Out: the tip-to-target error at every valid EM
// sample (RMS, mean, p95, max; overall, per beat and by heartbeat phase), latency and
// pipeline time (p50/p95/p99/max/mean), dropped frames, EM drop-outs and servo faults and
// modes, as JSON (AccuracyJson) and one self-contained HTML page (RenderAccuracyReport).
// The figures cover a window: from --from, else from when the servo began following
// (servo.csv), else the whole run. Units: mm, s (ms for latencies), image frame. Errors:
// std::invalid_argument when the alignment refuses, a plausibility check fails (unless
// forced), or no EM sample overlaps the target after alignment.
// Details: docs/report.md#metrics
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "formats/em_log.h"
#include "formats/run_record.h"
#include "report/em_alignment.h"

namespace echoservo::report {

struct AccuracyOptions {
  EmAlignmentOptions alignment;
  int phase_bins = 10;
  double min_rate_hz = 0.6;  // heart-rate search when run.json has none
  double max_rate_hz = 3.0;
  // Figures from this pipeline time on (s; the alignment uses the whole run): a run's start
  // (tracker initialising, servo catching up) is not what it is judged on. Not finite: from
  // servo.csv's first row in the following mode, else the whole run.
  double from_s = -std::numeric_limits<double>::infinity();
  std::string from_reason = "--from";  // why from_s, when it is finite
  // Where a given alignment.em_to_image came from ("--em-to-image", "run.json").
  std::string transform_source = "--em-to-image";
  // Where a given alignment.fixed_offset_s came from, shown in the report, e.g.
  // "--tracker-lag 0.034 s (given)" (report --tracker-lag; docs/report.md#tracker-lag).
  std::string offset_source = "--tracker-lag";
  // The tracker lag behind it (PLUS's sign: fixed_offset_s = −lag), NaN when none.
  double tracker_lag_s = std::numeric_limits<double>::quiet_NaN();
  AlignmentCheckLimits checks;
  // Give the figures even when a plausibility check fails (warnings, forced = true).
  bool force = false;
};

struct BeatError {
  double start_s = 0.0;  // the first evaluated sample of the beat
  std::size_t samples = 0;
  double rms_mm = 0.0;
};

struct TimingStats {
  std::size_t count = 0;
  double p50_ms = 0.0, p95_ms = 0.0, p99_ms = 0.0, max_ms = 0.0, mean_ms = 0.0;
};

struct DroppedFrames {
  std::size_t volumes = 0;          // rows of targets.csv
  std::size_t not_found = 0;        // found = 0
  std::size_t gaps = 0;             // gaps in acquired_s > 1.5 median periods
  std::size_t missing_in_gaps = 0;  // volumes those gaps miss
  double median_period_s = 0.0;
  std::vector<std::pair<double, double>> gap_spans_s;  // (from, to) of each gap
  std::size_t total() const { return not_found + missing_in_gaps; }
};

struct AccuracyMetrics {
  formats::EmLog em;  // as imported
  EmAlignment alignment;
  std::string target_source;  // "truth.csv" or "targets.csv"
  // The evaluated EM samples: pipeline time, mapped EM tip, target, error.
  std::vector<double> t_s;
  std::vector<Eigen::Vector3d> tip_mm, target_mm;
  std::vector<double> error_mm;
  double rms_mm = 0.0, mean_mm = 0.0, p95_mm = 0.0, max_mm = 0.0;
  // The cardiac phase model; heart_rate_hz 0 when no fit was possible (see notes).
  double heart_rate_hz = 0.0;
  std::string heart_rate_source;                           // "run.json", "target motion" or empty
  Eigen::Vector3d motion_axis = Eigen::Vector3d::UnitZ();  // principal axis of the target
  std::vector<BeatError> beats;
  std::vector<double> phase_rms_mm;  // phase_bins entries (NaN: no sample in the bin)
  std::vector<std::size_t> phase_samples;
  std::vector<double> latency_ms;  // applied − arrived per row of latency.csv
  TimingStats latency, pipeline;   // latency.csv; published − acquired
  DroppedFrames dropped;
  double servo_faults = 0.0;
  std::map<std::string, double> servo_mode_s;              // time in each servo mode
  std::optional<formats::ServoTimingRecord> servo_timing;  // the RUN's timing.json, when present
  // The RUN's tracker.json, when present: volumes acquired, missed by the scanner, shed by the
  // tracker (stale), processed.
  std::optional<formats::TrackerVolumeCounts> tracker_volumes;
  std::vector<std::string> notes;
  // The scored window: from window_from_s (−inf: the whole run) on, and why.
  double window_from_s = -std::numeric_limits<double>::infinity();
  std::string window_reason;
  std::string transform_source;  // "--em-to-image", "run.json" or "estimated"
  // The clock offset: "estimated" (searched), or where the given tracker lag came from.
  std::string offset_source;
  double tracker_lag_s = std::numeric_limits<double>::quiet_NaN();  // the given lag, s
  std::vector<AlignmentCheck> checks;
  bool forced = false;                // a check failed and options.force gave the figures
  std::vector<std::string> warnings;  // the failed checks' messages
};

// Throws std::invalid_argument when the alignment refuses, a plausibility check
// (CheckAlignment) fails without options.force, or no EM sample overlaps the target after
// alignment within the scored window.
AccuracyMetrics ComputeAccuracy(const formats::RunRecord& run, const formats::EmLog& em,
                                const AccuracyOptions& options = {});

// The scored window in words: "from 2.10 s: servo began following", "from 3.00 s: --from",
// "whole run: no servo.csv".
std::string WindowText(const AccuracyMetrics& metrics);

// p in [0, 1] of `values` by linear interpolation between order statistics; NaN when empty.
double Percentile(std::vector<double> values, double p);
TimingStats SummarizeMs(const std::vector<double>& values_ms);

struct AccuracyReportOptions {
  std::string run_path;  // as shown
  std::string em_path;
  std::string generated;           // date shown; empty: now (UTC)
  double reference_rms_mm = 0.86;  // the seed's trakSTAR tip-to-target RMS, for comparison
};

// The JSON summary (indented text): tip_to_target_rms_mm, per_beat_rms_mm, phase_rms_mm,
// latency_ms {p50, p95, p99, max, mean, count}, dropped_frames, em_time_offset_s,
// registration_rms_mm, em_samples, em_dropouts and the details (docs/report.md).
std::string AccuracyJson(const AccuracyMetrics& metrics, const AccuracyReportOptions& options);

// One self-contained HTML page.
std::string RenderAccuracyReport(const formats::RunRecord& run, const AccuracyMetrics& metrics,
                                 const AccuracyReportOptions& options);

}  // namespace echoservo::report
