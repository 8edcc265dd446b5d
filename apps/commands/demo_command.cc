// `echoservo demo [--duration S] [--out RUN_DIR] [--json] [...]`: the closed-loop demo on the
// simulated scanner and catheter (live/demo_run.h). JSON: {"tip_to_target_rms_mm",
// "true_tip_to_target_rms_mm", "latency_ms": {"p50", "p99", "max", "count"},
// "dropped_frames", "missed_acquisitions", "shed_volumes", "volumes", "detected",
// "estimates_accepted", "estimates_rejected", "estimates_rejected_by" {"link", "non_finite",
// "range", "time", "confidence"}, "em_samples", "em_dropouts", "servo_cycles", "servo_overruns",
// "limit_faults", "ekf_harmonics", "ekf_rate_hz", "run_dir", "realtime", "timing", "deadline"} (the
// last three as in `servo --json` and RUN/timing.json: live/servo_cycle_clock.h ServoTimingJson),
// and "em_stream": the --em-connect client's counts (RUN/em_stream.json; null without it), and
// "igtl_serve": the --igtl-serve detection server's counts (docs/slicer.md; null without it).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "apps/commands/em_connect_flags.h"
#include "apps/commands/igtl_serve_flags.h"
#include "apps/commands/live_commands.h"
#include "apps/commands/realtime_flags.h"
#include "apps/commands/report_command.h"
#include "apps/commands/set_flags.h"
#include "live/demo_run.h"

namespace echoservo::apps {
namespace {

namespace fs = std::filesystem;

struct DemoArgs {
  live::DemoOptions options;
  RealtimeFlags rt;
  std::string out;
  bool json = false;
  bool baseline = false;
  EmConnectFlags em;    // --em-connect: a PLUS server's EM stream writes em.csv
  IgtlServeFlags igtl;  // --igtl-serve: the detections to OpenIGTLink viewers (Slicer)
  SetFlags set;         // --set NAME=VALUE (live/pipeline_parameters.h), over the flags
};

// The demo's figures: JSON (--json) or lines, the baseline's and the report's with them.
void PrintDemoResult(const DemoArgs& a, const live::DemoResult& r,
                     const std::optional<live::DemoResult>& zoh,
                     const std::optional<double>& report_rms_mm, const std::string& report_error,
                     const nlohmann::json& igtl_serve, const nlohmann::json& em_stream) {
  if (a.json) {
    const nlohmann::json j = {
        {"tip_to_target_rms_mm", r.tip_to_target_rms_mm},
        {"true_tip_to_target_rms_mm", r.true_tip_to_target_rms_mm},
        {"scored_window",
         {{"from_s", std::isfinite(r.scored_from_s) ? nlohmann::json(r.scored_from_s)
                                                    : nlohmann::json(nullptr)},
          {"reason", r.scored_window}}},
        {"latency_ms",
         {{"p50", r.latency.p50_ms},
          {"p99", r.latency.p99_ms},
          {"max", r.latency.max_ms},
          {"count", r.latency.count}}},
        {"dropped_frames", r.dropped_frames},
        {"missed_acquisitions", r.missed_acquisitions},
        {"shed_volumes", r.shed_volumes},
        {"tracker_errors", r.tracker_errors},
        {"volumes", r.volumes},
        {"volumes_recorded", r.volumes_recorded},
        {"volumes_record_dropped", r.volumes_record_dropped},
        {"detected", r.detected},
        {"estimates_accepted", r.estimates_accepted},
        {"estimates_rejected", r.estimates_rejected},
        {"estimates_rejected_by",
         {{"link", r.rejected_link},
          {"non_finite", r.rejected_non_finite},
          {"range", r.rejected_range},
          {"time", r.rejected_time},
          {"confidence", r.rejected_confidence}}},
        {"em_samples", r.em_samples},
        {"em_dropouts", r.em_dropouts},
        {"servo_cycles", r.servo_cycles},
        {"servo_overruns", r.servo_overruns},
        {"limit_faults", r.limit_faults},
        {"limit_violations", r.limit_violations},
        {"resumes", r.resumes},
        {"stale_events", r.stale_events},
        {"target",
         {{"volumes", r.tracked_volumes},
          {"found", r.target_found},
          {"found_fraction", r.tracked_volumes ? static_cast<double>(r.target_found) /
                                                     static_cast<double>(r.tracked_volumes)
                                               : 0.0},
          {"contact_true", r.contact_true},
          {"contact_reported", r.contact_reported},
          {"contact_true_reported", r.contact_true_reported},
          {"contact_reported_apart", r.contact_reported_apart}}},
        {"ekf_harmonics", r.ekf_harmonics},
        {"ekf_rate_hz", r.ekf_rate_hz},
        {"run_dir", a.out.empty() ? nlohmann::json(nullptr) : nlohmann::json(a.out)}};
    nlohmann::json out = j;
    const nlohmann::json timing = nlohmann::json::parse(r.timing_json);
    for (const char* key : {"realtime", "timing", "deadline"}) out[key] = timing[key];
    if (!report_error.empty()) out["report_error"] = report_error;
    out["em_stream"] = em_stream;
    out["igtl_serve"] = igtl_serve;
    if (report_rms_mm) {
      out["report"] = (fs::path(a.out) / "report.html").string();
      out["report_tip_to_target_rms_mm"] = *report_rms_mm;  // EM aligned by the report itself
    }
    if (zoh) {
      out["baseline"] = {
          {"predictor", "zero_order_hold"},
          {"tip_to_target_rms_mm", zoh->tip_to_target_rms_mm},
          {"true_tip_to_target_rms_mm", zoh->true_tip_to_target_rms_mm},
          {"latency_ms", {{"p50", zoh->latency.p50_ms}, {"p99", zoh->latency.p99_ms}}},
          {"limit_violations", zoh->limit_violations}};
      out["baseline_ratio"] =
          r.tip_to_target_rms_mm > 0 ? zoh->tip_to_target_rms_mm / r.tip_to_target_rms_mm : 0.0;
    }
    std::cout << out.dump(2) << "\n";
    return;
  }
  std::printf(
      "tip-to-target RMS: %.3f mm (EM tracker), %.3f mm (true tip); seed water tank: 0.86 mm\n",
      r.tip_to_target_rms_mm, r.true_tip_to_target_rms_mm);
  if (std::isfinite(r.scored_from_s))
    std::printf("scored window: from %.2f s: %s\n", r.scored_from_s, r.scored_window.c_str());
  else
    std::printf("scored window: %s\n", r.scored_window.c_str());
  std::printf("latency arrival → setpoint: p50 %.2f ms, p99 %.2f ms, max %.2f ms (%llu volumes)\n",
              r.latency.p50_ms, r.latency.p99_ms, r.latency.max_ms,
              static_cast<unsigned long long>(r.latency.count));
  std::printf(
      "volumes %llu acquired (scanner: %llu acquisitions missed), %llu shed by the tracker "
      "(stale), detected %llu, dropped %llu in all; EM samples %llu (%llu drop-outs); servo "
      "overruns %llu\n",
      static_cast<unsigned long long>(r.volumes),
      static_cast<unsigned long long>(r.missed_acquisitions),
      static_cast<unsigned long long>(r.shed_volumes), static_cast<unsigned long long>(r.detected),
      static_cast<unsigned long long>(r.dropped_frames),
      static_cast<unsigned long long>(r.em_samples), static_cast<unsigned long long>(r.em_dropouts),
      static_cast<unsigned long long>(r.servo_overruns));
  std::printf(
      "servo timing: wake-up latency p50 %.0f / p99 %.0f / p99.9 %.0f / max %.0f us, cycle p99 "
      "%.0f us, overruns %.3f %%; deadline holds %llu, retractions %llu; real time: %s\n",
      r.timing.wakeup_latency.p50_us, r.timing.wakeup_latency.p99_us,
      r.timing.wakeup_latency.p999_us, r.timing.wakeup_latency.max_us,
      r.timing.cycle_duration.p99_us, 100.0 * r.timing.overrun_fraction,
      static_cast<unsigned long long>(r.deadline_holds),
      static_cast<unsigned long long>(r.deadline_retracts), r.realtime.Summary().c_str());
  if (a.options.save_volumes)
    std::printf("volumes recorded %llu, dropped by the recorder %llu%s%s\n",
                static_cast<unsigned long long>(r.volumes_recorded),
                static_cast<unsigned long long>(r.volumes_record_dropped),
                r.record_error.empty() ? "" : "; recording stopped: ", r.record_error.c_str());
  if (zoh)
    std::printf(
        "baseline (zero-order hold, same process): %.3f mm (EM), %.3f mm (true tip): %.1f× the "
        "EKF's error\n",
        zoh->tip_to_target_rms_mm, zoh->true_tip_to_target_rms_mm,
        r.tip_to_target_rms_mm > 0 ? zoh->tip_to_target_rms_mm / r.tip_to_target_rms_mm : 0.0);
  if (report_rms_mm)
    std::printf("run written to %s; its report (%s/report.html): %.3f mm\n", a.out.c_str(),
                a.out.c_str(), *report_rms_mm);
  else if (!a.out.empty())
    std::printf("run written to %s (no report: %s)\n", a.out.c_str(), report_error.c_str());
}

void RunDemoCommand(const DemoArgs& a) {
  live::DemoOptions o = a.options;
  o.settings = a.set.Parsed();  // over --standoff, --harmonics (live::DemoSettings)
  o.out_dir = a.out;
  o.realtime = ToRealtimeOptions(a.rt);
  o.watchdog = ToWatchdogConfig(a.rt, 1e-3);  // the simulated catheter's 1 kHz servo
  o.slow_reads = ToSlowReads(a.rt);
  if (!a.json) o.log = [](const std::string& line) { std::cerr << "demo: " << line << "\n"; };
  // --em-connect: the live EM stream replaces the simulated EM tracker in em.csv.
  live::EmStreamRecorder em(a.em, "demo");
  if (em.enabled()) {
    o.external_em = [&em](formats::RunWriter* writer) {
      em.Start(writer);
      return std::function<void()>([&em] { em.Stop(); });
    };
  }
  // --igtl-serve: each tracked volume to the OpenIGTLink viewers (docs/slicer.md), stamped
  // with its acquisition time on the system clock (the pipeline clock's offset, see demo_run.h).
  IgtlServe igtl(a.igtl, "demo");
  if (igtl.enabled()) {
    o.on_tracked = [&igtl](const live::TrackedVolume& t, const imaging::Volume& v,
                           double acquired_unix_s) { igtl.OnTracked(t, v, acquired_unix_s); };
  }
  const live::DemoResult r = live::RunDemo(o);
  const nlohmann::json igtl_serve = nlohmann::json::parse(igtl.Finish());
  const nlohmann::json em_stream = nlohmann::json::parse(em.Finish(a.out));
  // The baseline in the same process: the same run (seed, scene, catheter) with the tracker
  // publishing a zero-order hold of its newest measurement instead of the EKF's prediction.
  // The run's report, as `echoservo report RUN --from <metrics start>` writes it.
  std::optional<double> report_rms_mm;
  std::string report_error;
  if (!a.out.empty()) {
    try {
      report_rms_mm =
          WriteRunReport(a.out, (fs::path(a.out) / "report.html").string(), o.metrics_start_s);
    } catch (
        const std::exception& e) {  // the run is written either way; say why there is no report
      report_error = e.what();
      std::fprintf(stderr, "demo: no report for %s: %s\n", a.out.c_str(), e.what());
    }
  }
  std::optional<live::DemoResult> zoh;
  if (a.baseline) {
    live::DemoOptions b = o;
    b.zero_order_hold = true;
    b.out_dir.clear();
    b.save_volumes = false;
    b.external_em = nullptr;
    b.on_tracked = nullptr;
    if (o.log) o.log("baseline: the same run with a zero-order hold instead of the EKF");
    zoh = live::RunDemo(b);
  }
  PrintDemoResult(a, r, zoh, report_rms_mm, report_error, igtl_serve, em_stream);
}

}  // namespace

void AddLiveCommands(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* demo = app.add_subcommand("demo",
                                      "closed loop on the simulated scanner and catheter: tracker, "
                                      "heartbeat EKF, 1 kHz servo, EM tracker");
  auto& o = args->options;
  demo->add_option("--duration", o.duration_s, "run length, s (real time)")
      ->check(CLI::Range(0.5, 3600.0));
  demo->add_option("--rate", o.rate_hz, "volume rate, vol/s")->check(CLI::Range(1.0, 60.0));
  demo->add_option("--delay-min", o.delay_min_s, "imaging delay, lower end, s")
      ->check(CLI::Range(0.0, 1.0));
  demo->add_option("--delay-max", o.delay_max_s, "imaging delay, upper end, s")
      ->check(CLI::Range(0.0, 1.0));
  demo->add_option("--heart-rate", o.heart_rate_bpm, "target heart rate, bpm")
      ->check(CLI::Range(30.0, 180.0));
  demo->add_option("--target-p2p", o.target_p2p_mm, "target excursion, mm peak to peak")
      ->check(CLI::Range(0.1, 20.0));
  demo->add_option("--standoff", o.standoff_mm, "tip-to-target standoff along the axis, mm")
      ->check(CLI::Range(0.0, 30.0));
  demo->add_option("--metrics-start", o.metrics_start_s,
                   "figures from this time on, s (default: the scored window `report` uses, "
                   "from when the servo follows plus two heartbeats)")
      ->check(CLI::Range(0.0, 3600.0));
  demo->add_option("--seed", o.seed, "simulation seed");
  demo->add_option("--harmonics", o.harmonics,
                   "EKF harmonics (it publishes after 2·(2·N + 4) volumes)")
      ->check(CLI::Range(1, 12));
  demo->add_option("--sheath-id", o.sheath_id_mm,
                   "catheter sheath inner diameter, mm (seed water tank: 1.59)");
  demo->add_option("--guidewire-od", o.guidewire_od_mm,
                   "guidewire outer diameter, mm (seed water tank: 1.50)");
  demo->add_option("--dds-domain", o.dds_domain,
                   "DDS domain of the tracker → servo link (loopback only)")
      ->check(CLI::Range(0, 232));
  demo->add_option("--secure", o.secure_dir,
                   "DDS-Security: the credential directory of `echoservo security init DIR` "
                   "(tracker and servo identities)");
  demo->add_option("--out", args->out,
                   "write the run (RUN directory: targets, servo, latency, EM log, truth)");
  demo->add_flag("--save-volumes", o.save_volumes,
                 "also record the volumes the tracker receives to RUN/volumes.igs.mhd (+ .raw), "
                 "on a recorder thread (a full queue drops, counted), "
                 "for `track --replay`");
  demo->add_flag("--baseline", args->baseline,
                 "then run the same demo with a zero-order hold instead of the EKF (same process) "
                 "and report the ratio");
  AddRealtimeFlags(*demo, args->rt);
  AddEmConnectFlags(*demo, args->em);
  AddIgtlServeFlags(*demo, args->igtl);
  AddSetFlags(*demo, args->set);
  demo->add_flag("--json", args->json, "print the figures as JSON");
  demo->callback([args] { RunDemoCommand(*args); });
  AddTrackCommand(app);
  AddServoCommand(app);
  AddOperatorCommand(app);
  AddFaultsCommand(app);
  AddSecurityCommand(app);
}

}  // namespace echoservo::apps
