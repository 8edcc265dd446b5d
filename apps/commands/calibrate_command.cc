// `echoservo calibrate temporal`: the lag of a tracker's pose stream behind its ultrasound
// video stream (PLUS's temporal calibration), and `echoservo calibrate sweep`: a simulated
// water-tank sweep with a known lag, written as a PLUS video and tracker sequence.
#include "apps/commands/calibrate_command.h"

#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "apps/output.h"
#include "imaging/io/plus_sequence.h"
#include "imaging/sim/water_tank_sweep.h"
#include "tracking/temporal_calibration.h"

namespace echoservo::apps {
namespace {

struct TemporalFlags {
  std::string video;
  std::string tracker;
  std::string tool;
  double max_lag_s = 2.0;
  double resolution_s = 0.001;
  bool json = false;
};

void RunTemporal(const TemporalFlags& f) {
  // Each input is read and validated before the other's work (a wrong tool is named before
  // the video's frames are searched).
  const imaging::PlusSequence tracker_seq = imaging::ReadPlusSequence(f.tracker);
  const tracking::TrackerSignal tracker =
      tracking::ProbeMotionSignal(tracker_seq, f.tool, f.tracker);
  const imaging::PlusSequence video_seq = imaging::ReadPlusSequence(f.video);
  const tracking::VideoSignal video = tracking::ReflectorSignal(video_seq, f.video);
  tracking::LagOptions lo;
  lo.max_lag_s = f.max_lag_s;
  lo.resolution_s = f.resolution_s;
  const tracking::LagResult r =
      tracking::EstimateTrackerLag(video.depth_px, tracker.position_mm, lo, f.video, f.tracker);

  if (f.json) {
    nlohmann::ordered_json j;
    j["tracker_lag_s"] = r.tracker_lag_s;
    j["video_frames_used"] = r.video_samples_used;
    j["tracker_frames_used"] = r.tracker_samples_used;
    j["correlation"] = r.correlation;
    j["sign_convention"] =
        "PLUS: the tracker stream lags the video stream by tracker_lag_s (tracker timestamps "
        "are late by it; subtract it from them to reach the video clock)";
    j["tool"] = tracker.tool;
    j["tracker_signal_inverted"] = r.inverted;
    j["other_polarity"] = {{"tracker_lag_s", r.other_lag_s}, {"correlation", r.other_correlation}};
    j["video"] = {{"file", f.video},
                  {"frames", video.frames},
                  {"invalid", video.invalid},
                  {"no_line", video.no_line},
                  {"duplicate_timestamps", video.duplicates},
                  {"static_background_removed", video.background_subtracted},
                  {"frame_size_px", {video.width, video.height}},
                  {"reflector_peak_to_peak_px", r.video_p2p_px},
                  {"reflector_peak_to_peak_mm", r.video_p2p_px * video.spacing_mm}};
    nlohmann::ordered_json not_ok = nlohmann::ordered_json::object();
    for (const auto& [status, n] : tracker.not_ok) not_ok[status] = n;
    j["tracker"] = {{"file", f.tracker},
                    {"frames", tracker.frames},
                    {"not_ok", not_ok},
                    {"duplicate_timestamps", tracker.duplicates},
                    {"principal_axis", {tracker.axis.x(), tracker.axis.y(), tracker.axis.z()}},
                    {"peak_to_peak_mm", r.tracker_p2p_mm}};
    j["window_s"] = {r.window_from_s, r.window_to_s};
    j["max_lag_s"] = lo.max_lag_s;
    j["resolution_s"] = lo.resolution_s;
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::cout << "tracker lag " << Fixed(r.tracker_lag_s, 4) << " s ("
            << Fixed(1000.0 * r.tracker_lag_s, 1)
            << " ms; > 0: the tracker stream lags the video, PLUS's sign), correlation "
            << Fixed(r.correlation, 4) << "\n"
            << "video " << f.video << ": " << r.video_samples_used << " frames used of "
            << video.frames << " (" << video.invalid << " invalid, " << video.no_line
            << " without a reflector line), reflector " << Fixed(r.video_p2p_px, 1)
            << " px peak-to-peak\n"
            << "tracker " << f.tracker << " (" << tracker.tool << "): " << r.tracker_samples_used
            << " frames used of " << tracker.frames << ", " << Fixed(r.tracker_p2p_mm, 1)
            << " mm peak-to-peak along its principal direction\n"
            << "polarity: reflector depth " << (r.inverted ? "falls" : "rises")
            << " as the tracked position rises; the other polarity's best: lag "
            << Fixed(r.other_lag_s, 4) << " s, correlation " << Fixed(r.other_correlation, 4)
            << "\n";
}

struct SweepFlags {
  imaging::sim::WaterTankSweepOptions options;
  std::string video;
  std::string tracker;
};

void RunSweep(const SweepFlags& f) {
  const imaging::sim::WaterTankSweep sweep = imaging::sim::MakeWaterTankSweep(f.options);
  imaging::WritePlusSequence(sweep.video, f.video);
  imaging::WritePlusSequence(sweep.tracker, f.tracker);
  std::cout << "wrote " << f.video << " (" << sweep.video.frames.size() << " frames) and "
            << f.tracker << " (" << sweep.tracker.frames.size()
            << " ProbeToTracker poses), tracker lag " << Fixed(f.options.tracker_lag_s, 4)
            << " s\n";
}

}  // namespace

void AddCalibrateCommand(CLI::App& app) {
  auto* cal = app.add_subcommand("calibrate", "Calibrations: temporal (tracker lag)");
  cal->require_subcommand(1);

  auto t = std::make_shared<TemporalFlags>();
  auto* temporal = cal->add_subcommand(
      "temporal",
      "Lag of a tracked probe's pose stream behind its ultrasound video, from a sweep over a "
      "water-tank bottom (PLUS's method and sign; docs/calibration.md)");
  temporal->add_option("--video", t->video, "PLUS video sequence (.igs.mha/.igs.nrrd)")->required();
  temporal->add_option("--tracker", t->tracker, "PLUS tracker sequence (.igs.mha/.igs.nrrd)")
      ->required();
  temporal->add_option("--tool", t->tool,
                       "Probe tool (default ProbeToTracker, else the file's only tool)");
  temporal->add_option("--max-lag", t->max_lag_s, "Search window ±, s (default 2, PLUS's)")
      ->check(CLI::Range(0.001, 30.0));
  temporal->add_option("--resolution", t->resolution_s, "Fine scan step, s (default 0.001)")
      ->check(CLI::Range(1e-5, 1.0));
  temporal->add_flag("--json", t->json, "Print the result as JSON");
  temporal->callback([t] { RunTemporal(*t); });

  auto s = std::make_shared<SweepFlags>();
  auto* sweep = cal->add_subcommand(
      "sweep",
      "Write a simulated water-tank sweep (simulated scanner + tracker) with a known tracker "
      "lag, for `calibrate temporal`");
  sweep->add_option("--video", s->video, "PLUS video sequence to write (.igs.mha)")->required();
  sweep->add_option("--tracker", s->tracker, "PLUS tracker sequence to write (.igs.mha)")
      ->required();
  sweep
      ->add_option("--lag", s->options.tracker_lag_s,
                   "Tracker lag, s (PLUS's sign: > 0 the tracker lags; default 0)")
      ->check(CLI::Range(-5.0, 5.0));
  sweep->add_option("--duration", s->options.duration_s, "Recording length, s (default 8)")
      ->check(CLI::Range(0.1, 600.0));
  sweep->add_option("--video-rate", s->options.video_rate_hz, "Frames per second (default 25)")
      ->check(CLI::Range(1.0, 200.0));
  sweep
      ->add_option("--tracker-rate", s->options.tracker_rate_hz,
                   "Tracker samples per second (default 40)")
      ->check(CLI::Range(1.0, 1000.0));
  sweep
      ->add_option("--amplitude", s->options.amplitude_mm,
                   "Probe motion amplitude, mm (default 12)")
      ->check(CLI::Range(0.1, 40.0));
  sweep->add_option("--seed", s->options.seed, "Speckle and tracker noise seed (default 1)");
  sweep->callback([s] { RunSweep(*s); });
}

}  // namespace echoservo::apps
