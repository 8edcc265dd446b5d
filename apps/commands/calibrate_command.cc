// `echoservo calibrate temporal`: the lag of a tracker's pose stream behind its ultrasound
// video stream (PLUS's temporal calibration, stage by stage, with a confidence and refusals),
// and `echoservo calibrate sweep`: a simulated water-tank sweep with a known lag, written as
// a PLUS video and tracker sequence.
#include "apps/commands/calibrate_command.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

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
  double max_lag_s = 0.5;
  double resolution_s = 0.001;
  std::vector<int> clip_rect;  // X Y W H, pixels
  double pixel_spacing_mm = 0.0;
  bool subtract_background = false;
  double min_correlation = 0.9;
  double max_lag_sd_s = 0.005;
  bool json = false;
};

void RunTemporal(const TemporalFlags& f) {
  tracking::ReflectorLineOptions line;
  if (!f.clip_rect.empty()) {
    if (f.clip_rect.size() != 4 || f.clip_rect[2] <= 0 || f.clip_rect[3] <= 0)
      throw std::invalid_argument(
          "--clip-rect takes 4 integers, X Y WIDTH HEIGHT (pixels, width and height > 0)");
    line.clip = {f.clip_rect[0], f.clip_rect[1], f.clip_rect[2], f.clip_rect[3]};
  }
  line.subtract_static_background = f.subtract_background;
  // Each input is read and validated before the other's work (a wrong tool is named before
  // the video's frames are searched).
  const imaging::PlusSequence tracker_seq = imaging::ReadPlusSequence(f.tracker);
  const tracking::TrackerPoses tracker = tracking::ReadProbePoses(tracker_seq, f.tool, f.tracker);
  const imaging::PlusSequence video_seq = imaging::ReadPlusSequence(f.video);
  tracking::VideoSignal video = tracking::ReflectorSignal(video_seq, f.video, line);
  std::string spacing_source = video.spacing_known ? "the video's ElementSpacing" : "";
  if (f.pixel_spacing_mm > 0.0) {
    video.spacing_mm = f.pixel_spacing_mm;
    video.spacing_known = true;
    spacing_source = "--pixel-spacing";
  }
  tracking::LagOptions lo;
  lo.max_lag_s = f.max_lag_s;
  lo.resolution_s = f.resolution_s;
  lo.min_peak_r = f.min_correlation;
  lo.max_lag_sd_s = f.max_lag_sd_s;
  const tracking::LagResult r =
      tracking::EstimateTrackerLag(video, tracker, lo, f.video, f.tracker);
  const tracking::LagConfidence& c = r.confidence;
  const std::string no_spacing =
      "unknown: the video's ElementSpacing is MetaIO's default 1 1 (PLUS writes it for raw "
      "frame buffers); give --pixel-spacing for mm";

  if (f.json) {
    using Json = nlohmann::ordered_json;
    const auto number_or_null = [](double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); };
    Json j;
    j["tracker_lag_s"] = r.tracker_lag_s;
    j["video_frames_used"] = r.video_samples_used;
    j["tracker_frames_used"] = r.tracker_samples_used;
    j["correlation"] = r.correlation;
    j["sign_convention"] =
        "PLUS: the tracker stream lags the video stream by tracker_lag_s (tracker timestamps "
        "are late by it; subtract it from them to reach the video clock)";
    j["tool"] = tracker.tool;
    j["tracker_signal_inverted"] = r.inverted;
    j["other_polarity"] = {{"tracker_lag_s", r.other_lag_s},
                           {"best_lag_s", c.other_polarity_lag_s},
                           {"correlation", c.other_polarity_r}};
    j["confidence"] = {{"frames_compared", c.samples},
                       {"peak_lag_s", c.peak_lag_s},
                       {"peak_correlation", c.peak_r},
                       {"lag_sd_s", c.lag_sd_s},
                       {"misfit_doubling_width_s", c.misfit_width_s},
                       {"half_height_width_s", c.fwhm_s},
                       {"second_peak", std::isnan(c.second_r) ? Json(nullptr)
                                                              : Json{{"lag_s", c.second_lag_s},
                                                                     {"correlation", c.second_r}}}};
    j["plus"] = {{"coarse_step_s", r.coarse_step_s},
                 {"coarse_lag_s", r.coarse_lag_s},
                 {"common_range_s", {r.common_from_s, r.common_to_s}},
                 {"tracker_range_s", {r.moving_from_s, r.moving_to_s}},
                 {"sum_squared_differences", r.plus_ssd},
                 {"calibration_error_mm", r.plus_calibration_error},
                 {"max_calibration_error_mm", number_or_null(r.plus_max_calibration_error)}};
    j["video"] = {
        {"file", f.video},
        {"frames", video.frames},
        {"invalid", video.invalid},
        {"no_line", video.no_line},
        {"duplicate_timestamps", video.duplicates},
        {"clip_rect_px", {video.region.x, video.region.y, video.region.width, video.region.height}},
        {"static_background_removed", video.background_subtracted},
        {"frame_size_px", {video.width, video.height}},
        {"reflector_peak_to_peak_px", r.video_p2p_px},
        {"reflector_peak_to_peak_mm",
         video.spacing_known ? Json(r.video_p2p_px * video.spacing_mm) : Json(nullptr)},
        {"pixel_spacing_mm", video.spacing_known ? Json(video.spacing_mm) : Json(nullptr)},
        {"pixel_spacing", video.spacing_known ? spacing_source : no_spacing}};
    Json not_ok = Json::object();
    for (const auto& [status, n] : tracker.not_ok) not_ok[status] = n;
    j["tracker"] = {{"file", f.tracker},
                    {"frames", tracker.frames},
                    {"not_ok", not_ok},
                    {"duplicate_timestamps", tracker.duplicates},
                    {"principal_axis", {r.axis.x(), r.axis.y(), r.axis.z()}},
                    {"peak_to_peak_mm", r.tracker_p2p_mm}};
    j["window_s"] = {r.common_from_s, r.common_to_s};
    j["max_lag_s"] = lo.max_lag_s;
    j["resolution_s"] = lo.resolution_s;
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::cout << "tracker lag " << Fixed(r.tracker_lag_s, 4) << " s ("
            << Fixed(1000.0 * r.tracker_lag_s, 2)
            << " ms; > 0: the tracker stream lags the video, PLUS's sign and grid)\n"
            << "confidence: correlation " << Fixed(c.peak_r, 4) << " peaking at "
            << Fixed(1000.0 * c.peak_lag_s, 2) << " ms, lag SD " << Fixed(1000.0 * c.lag_sd_s, 2)
            << " ms, peak " << Fixed(1000.0 * c.fwhm_s, 0) << " ms wide at half height; "
            << (std::isnan(c.second_r) ? std::string("no second peak")
                                       : "second peak " + Fixed(1000.0 * c.second_lag_s, 1) +
                                             " ms (r " + Fixed(c.second_r, 4) + ")")
            << "\n"
            << "video " << f.video << ": " << r.video_samples_used << " frames used of "
            << video.frames << " (" << video.invalid << " invalid, " << video.no_line
            << " without a reflector line), reflector " << Fixed(r.video_p2p_px, 1)
            << " px peak-to-peak"
            << (video.spacing_known ? " (" + Fixed(r.video_p2p_px * video.spacing_mm, 2) + " mm)"
                                    : " (pixel spacing " + no_spacing + ")")
            << "\n"
            << "tracker " << f.tracker << " (" << tracker.tool << "): " << r.tracker_samples_used
            << " poses used of " << tracker.frames << ", " << Fixed(r.tracker_p2p_mm, 1)
            << " mm peak-to-peak along its principal direction\n"
            << "polarity: reflector depth " << (r.inverted ? "falls" : "rises")
            << " as the tracked position rises; the other polarity's best: "
            << Fixed(1000.0 * c.other_polarity_lag_s, 1) << " ms (r "
            << Fixed(c.other_polarity_r, 4) << ")\n"
            << "PLUS: calibration error " << Fixed(r.plus_calibration_error, 3) << " mm, max "
            << Fixed(r.plus_max_calibration_error, 3) << " mm\n";
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
      "water-tank bottom (PLUS's method, sign and defaults; docs/calibration.md)");
  temporal->add_option("--video", t->video, "PLUS video sequence (.igs.mha/.igs.nrrd)")->required();
  temporal->add_option("--tracker", t->tracker, "PLUS tracker sequence (.igs.mha/.igs.nrrd)")
      ->required();
  temporal->add_option("--tool", t->tool,
                       "Probe tool (default ProbeToTracker, else the file's only tool); AToB "
                       "absent from the file is composed from AToC and BToC, e.g. "
                       "ProbeToReference as PLUS's command-line test uses");
  temporal
      ->add_option("--max-lag", t->max_lag_s,
                   "Search window ±, s; the tracker is cropped by it at each end (default 0.5, "
                   "PLUS's)")
      ->check(CLI::Range(0.001, 30.0));
  temporal->add_option("--resolution", t->resolution_s, "Fine scan step, s (default 0.001)")
      ->check(CLI::Range(1e-4, 1.0));
  temporal
      ->add_option("--clip-rect", t->clip_rect,
                   "X Y WIDTH HEIGHT: the pixels searched for the reflector (PLUS's "
                   "ClipRectangleOrigin/Size; default the whole frame)")
      ->expected(4);
  temporal
      ->add_option("--pixel-spacing", t->pixel_spacing_mm,
                   "Depth pixel spacing, mm, for a video that gives none (ElementSpacing 1 1)")
      ->check(CLI::Range(1e-4, 100.0));
  temporal->add_flag("--subtract-background", t->subtract_background,
                     "Remove the sweep's static background before searching (not PLUS's; for a "
                     "ring-down brighter than the reflector, instead of --clip-rect)");
  temporal
      ->add_option("--min-correlation", t->min_correlation,
                   "Refuse below this correlation at the lag (default 0.9)")
      ->check(CLI::Range(-1.0, 1.0));
  temporal
      ->add_option("--max-lag-sd", t->max_lag_sd_s,
                   "Refuse when the lag's SD exceeds this, s (default 0.005)")
      ->check(CLI::Range(1e-6, 1.0));
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
