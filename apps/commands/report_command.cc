// `echoservo report RUN`: tip-to-target accuracy from an EM-tracker log, latency and
// dropped frames of a recorded run, as HTML and JSON.
#include "apps/commands/report_command.h"

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <utility>

#include "apps/output.h"
#include "formats/run_record.h"
#include "imaging/io/em_log_import.h"
#include "report/accuracy_report.h"

namespace echoservo::apps {
namespace {

// 12 or 16 numbers, row-major: a rigid transform (mm).
// --tracker-lag: a number of seconds, or the JSON a `calibrate temporal --json` printed
// (its tracker_lag_s). Returns the lag and the words the report shows for its source.
std::pair<double, std::string> ParseTrackerLag(const std::string& text) {
  std::size_t used = 0;
  double lag = std::numeric_limits<double>::quiet_NaN();
  try {
    lag = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used > 0 && used == text.size()) {
    if (!std::isfinite(lag) || std::abs(lag) > 60.0)
      throw std::invalid_argument("--tracker-lag " + text + ": not a lag in s within ±60");
    return {lag, "--tracker-lag " + Fixed(lag, 4) + " s (given)"};
  }
  std::ifstream in(text);
  if (!in) {
    throw std::invalid_argument("--tracker-lag " + text +
                                ": neither a number of seconds nor a readable JSON file (the "
                                "output of `echoservo calibrate temporal --json`)");
  }
  const auto j = nlohmann::json::parse(in, nullptr, false);
  if (!j.is_object() || !j.contains("tracker_lag_s") || !j["tracker_lag_s"].is_number() ||
      !std::isfinite(j["tracker_lag_s"].get<double>()) ||
      std::abs(j["tracker_lag_s"].get<double>()) > 60.0) {
    throw std::invalid_argument("--tracker-lag " + text +
                                ": not the JSON of `echoservo calibrate temporal --json` (no "
                                "finite number 'tracker_lag_s' within ±60 s)");
  }
  lag = j["tracker_lag_s"].get<double>();
  std::string source = "--tracker-lag " + text + ": " + Fixed(lag, 4) + " s (calibrate temporal";
  if (j.contains("correlation") && j["correlation"].is_number())
    source += ", correlation " + Fixed(j["correlation"].get<double>(), 4);
  if (j.contains("video_frames_used") && j["video_frames_used"].is_number())
    source += ", " + std::to_string(j["video_frames_used"].get<long long>()) + " video frames";
  return {lag, source + ")"};
}

struct Produced {
  report::AccuracyMetrics metrics;
  report::AccuracyReportOptions options;
  formats::EmLog em;
};

// --out must name a file that can be written; a folder or a failed write is the user's
// mistake, named as such, and leaves no temporary file behind.
void CheckOut(const std::string& out) {
  std::error_code ec;
  if (std::filesystem::is_directory(out, ec)) {
    throw std::invalid_argument("--out " + out +
                                ": is a folder; give the HTML file to write (e.g. " +
                                (std::filesystem::path(out) / "report.html").string() + ")");
  }
}

void WritePage(const std::string& out, const std::string& html) {
  CheckOut(out);
  try {
    WriteFileAtomically(out, html);
  } catch (const std::exception& e) {
    std::error_code ec;
    std::filesystem::remove(out + ".tmp", ec);
    throw std::invalid_argument("--out " + out + ": cannot write the report (" + e.what() + ")");
  }
}

// Reads the run and its EM log, computes the metrics and writes the HTML page.
// An empty --out (the Python API) writes no page.
Produced Produce(const ReportFlags& f) {
  if (!f.out.empty()) CheckOut(f.out);  // before the work
  const formats::RunRecord run = formats::ReadRunRecord(f.run);
  for (const std::string& w : run.info.warnings) std::fprintf(stderr, "report: %s\n", w.c_str());
  std::string em_path = f.em;
  if (em_path.empty()) {
    if (!run.has_em) {
      throw std::invalid_argument(f.run + ": the run has no em.csv; give the EM log with --em");
    }
    em_path = run.EmPath().string();
  }
  formats::EmImportOptions io;
  io.format = formats::ParseEmLogFormat(f.em_format);
  if (!f.em_units.empty()) io.units = formats::ParseLengthUnit(f.em_units);
  io.sensor = f.sensor;
  const formats::EmLog em = imaging::ReadEmLog(em_path, io);

  report::AccuracyOptions ao;
  ao.alignment.max_offset_s = f.max_offset_s;
  ao.alignment.offset_center_s = f.offset_center_s;
  if (!f.em_to_image.empty()) {
    ao.alignment.em_to_image = formats::ParseRigidTransform(f.em_to_image, "--em-to-image");
    ao.transform_source = "--em-to-image";
  } else {
    // A run may carry its EM→image calibration (run.json "em_to_image": 12 or 16 numbers,
    // row-major, mm), measured before the run: a catheter moving along its axis cannot
    // give the rotation about it.
    if (run.info.meta.em_to_image) {
      ao.alignment.em_to_image = *run.info.meta.em_to_image;
      ao.transform_source = "run.json";
    }
  }
  if (!f.tracker_lag.empty()) {
    if (std::isfinite(f.offset_center_s))
      throw std::invalid_argument(
          "--tracker-lag and --offset-center: give one (a given lag is not searched)");
    // A lag relates two stamps of one clock: the run's times must be on the EM tracker's
    // (system) clock, not the demo's pipeline clock (s since the run's start).
    if (run.info.meta.time_base == formats::RunTimeBase::kPipeline)
      throw std::invalid_argument(
          "--tracker-lag: " + f.run +
          "/run.json says time_base 'pipeline': the run's times count from its start, not on "
          "the EM tracker's clock, so a lag alone does not give the clock offset; leave it "
          "to the report's search (drop --tracker-lag)");
    const auto [lag, source] = ParseTrackerLag(f.tracker_lag);
    // PLUS's sign: the EM (tracker) timestamps are late by the lag, t_image = t_EM − lag.
    ao.alignment.fixed_offset_s = -lag;
    ao.tracker_lag_s = lag;
    ao.offset_source = source;
  }
  ao.phase_bins = f.phase_bins;
  if (f.from_s) {
    ao.from_s = *f.from_s;
    ao.from_reason = f.from_reason;
  }
  ao.force = f.force;
  const report::AccuracyMetrics m = report::ComputeAccuracy(run, em, ao);

  report::AccuracyReportOptions ro;
  ro.run_path = f.run;
  ro.em_path = em_path;
  if (!f.out.empty()) WritePage(f.out, report::RenderAccuracyReport(run, m, ro));
  return {m, ro, em};
}

void RunReport(const ReportFlags& f) {
  const Produced p = Produce(f);
  const report::AccuracyMetrics& m = p.metrics;
  const report::AccuracyReportOptions& ro = p.options;
  const formats::EmLog& em = p.em;
  for (const std::string& w : m.warnings)
    std::cerr << "WARNING (--force): the EM log failed a plausibility check: " << w << "\n";
  if (f.json) {
    std::cout << report::AccuracyJson(m, ro) << "\n";
    return;
  }
  if (m.forced)
    std::cout << "WARNING: figures forced (--force) although the EM log failed the "
                 "plausibility checks; they may not measure this run\n";
  std::cout << "wrote " << f.out << "\n"
            << "tip-to-target RMS " << Fixed(m.rms_mm, 3) << " mm over " << m.error_mm.size()
            << " EM samples against " << m.target_source << " (seed "
            << Fixed(ro.reference_rms_mm, 2) << " mm)\n"
            << "EM: " << em.samples.size() << " samples, " << em.dropouts()
            << " drop-outs; clock offset " << Fixed(m.alignment.em_time_offset_s, 4) << " s ("
            << (m.alignment.fixed_offset ? "tracker lag " + m.offset_source : "estimated")
            << "), registration RMS " << Fixed(m.alignment.residual_rms_mm, 3) << " mm over "
            << m.alignment.pairs << " pairs; EM→image transform " << m.transform_source << "\n"
            << "scored window: " << report::WindowText(m) << "\n";
  if (m.latency.count > 0) {
    std::cout << "latency p50/p95/p99/max " << Fixed(m.latency.p50_ms, 1) << "/"
              << Fixed(m.latency.p95_ms, 1) << "/" << Fixed(m.latency.p99_ms, 1) << "/"
              << Fixed(m.latency.max_ms, 1) << " ms\n";
  }
  std::cout << "dropped frames " << m.dropped.total() << " of " << m.dropped.volumes << "\n";
  if (m.tracker_volumes)
    std::cout << "volumes: " << m.tracker_volumes->acquired << " acquired, "
              << m.tracker_volumes->missed << " acquisitions missed by the scanner, "
              << m.tracker_volumes->shed << " shed by the tracker (stale)\n";
  if (m.servo_timing) {
    const formats::ServoTimingRecord& t = *m.servo_timing;
    std::cout << "servo timing (" << t.realtime_summary << "): wake-up latency p50/p99/p99.9/max "
              << Fixed(t.wakeup_p50_us, 0) << "/" << Fixed(t.wakeup_p99_us, 0) << "/"
              << Fixed(t.wakeup_p999_us, 0) << "/" << Fixed(t.wakeup_max_us, 0) << " us, overruns "
              << t.overruns << " of " << t.cycles << " cycles, deadline holds " << t.deadline_holds
              << ", retractions " << t.deadline_retracts << "\n";
  }
  for (const std::string& n : m.notes) std::cout << "note: " << n << "\n";
}

}  // namespace

ReportResult ProduceReport(const ReportFlags& f) {
  Produced p = Produce(f);
  ReportResult r;
  r.json = report::AccuracyJson(p.metrics, p.options);
  r.metrics = std::move(p.metrics);
  return r;
}

double WriteRunReport(const std::string& run_dir, const std::string& html_path, double from_s) {
  ReportFlags f;
  f.run = run_dir;
  f.out = html_path;
  if (std::isfinite(from_s)) {  // else the scored window (report/scored_window.h)
    f.from_s = from_s;
    f.from_reason = "demo --metrics-start";
  }
  return Produce(f).metrics.rms_mm;
}

void AddReportCommand(CLI::App& app) {
  auto f = std::make_shared<ReportFlags>();
  auto* cmd = app.add_subcommand(
      "report",
      "Accuracy of a recorded run: tip-to-target error from an EM-tracker log, per beat "
      "and heartbeat phase, latency, dropped frames (HTML and JSON)");
  cmd->add_option("RUN", f->run, "RUN directory (run.json, targets.csv, …; docs/report.md)")
      ->required();
  cmd->add_option("--em", f->em, "EM-tracker log (default: RUN/em.csv)");
  cmd->add_option("--em-format", f->em_format, "auto|plus|aurora|sim (default auto)");
  cmd->add_option("--em-units", f->em_units,
                  "mm|in: the EM log's units (default: the file's own, else mm; inches must be "
                  "declared)");
  cmd->add_option(
      "--sensor", f->sensor,
      "Aurora: sensor index (1-based) or letter; PLUS: tool name (e.g. StylusToTracker)");
  cmd->add_option("--out", f->out, "HTML report to write")->required();
  cmd->add_option("--max-offset", f->max_offset_s,
                  "Half-width of the EM clock offset search, s (default 2)");
  cmd->add_option("--offset-center", f->offset_center_s,
                  "Centre of the offset search, s (default: first volume time − first EM time)");
  cmd->add_option("--from", f->from_s,
                  "Figures from this pipeline time on, s (the alignment uses the whole run; "
                  "default: when the servo began following, from servo.csv)")
      ->check(CLI::Range(-1e9, 1e9));
  cmd->add_option("--em-to-image", f->em_to_image,
                  "Known EM→image transform, 12 or 16 comma-separated numbers, row-major, mm: "
                  "only the clock offset is estimated");
  cmd->add_option("--tracker-lag", f->tracker_lag,
                  "Known tracker lag, s (PLUS's sign), or the JSON file of `calibrate temporal "
                  "--json`: the EM clock offset is not searched but set to -lag");
  cmd->add_option("--phase-bins", f->phase_bins, "Heartbeat phase bins (default 10)");
  cmd->add_flag("--json", f->json, "Print the figures as JSON");
  cmd->add_flag("--force", f->force,
                "Give the figures even when the EM log fails the plausibility checks "
                "(marked with a warning in the page and the JSON)");
  cmd->callback([f] { RunReport(*f); });
}

}  // namespace echoservo::apps
