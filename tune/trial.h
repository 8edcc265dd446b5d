// One tuning trial: a recording replayed through the tracker path with one parameter set
// (live/pipeline_parameters.h), every stage a parameter can change recorded and scored.
//
// Recordings: a PLUS sequence file (.igs.mha/.igs.mhd/.nrrd; with per-frame ground truth,
// imaging/io/truth_fields.h, where the simulated scanner made it), or a RUN directory
// (docs/report.md) holding volumes.igs.mhd and, optionally, em.csv + run.json (the EM
// log and its calibration). Scores (metric names below; each only where the recording has
// what it needs):
//   detection  — the detector's tip, target and axis against the truth fields, per volume;
//   prediction — after each measurement at t_i the shipped prediction at t_i + latency_s,
//                against the later measurements (interpolated) and against the truth;
//   loop       — the 1 kHz servo (live::ServoNode on the simulated catheter, live/
//                sim_catheter.h) re-simulated on the recording's clock, following the
//                replayed estimates, each delivered delay_s after its acquisition:
//                tip-to-target RMS against the truth target (else the measured one);
//   em         — the replayed targets against the recording's EM log through the report's
//                alignment (report/accuracy_report.h), as `echoservo report` scores a run;
//   latency    — the tracker's processing time per volume (host-dependent: not a score to
//                compare across machines).
// Frames: detection errors in the volume's image frame (mm); prediction and loop errors
// along the catheter axis (mm). Times: the recording's clock (s).
// The re-simulated loop: the imaged catheter in a replay does not move with the re-simulated
// plant, so the follower is given, as each estimate's imaged tip (tip_axis_mm), the plant's
// tip at that volume's acquisition plus the constant image↔catheter offset of the first
// detection (its tip's axis coordinate less the plant's tip then): the image answers the
// catheter as the live scene's does, with scale 1. The plant's tip is scored in the same
// axis coordinates, anchored at the first frame's true tip (else the first detection's).
// Errors: InspectRecording and RunTrial throw std::invalid_argument naming the recording
// and why (missing, unreadable, no volumes, a metric that needs truth or EM it lacks);
// RunTrial's result reports per-volume failures as counts, not exceptions.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "live/pipeline_parameters.h"

namespace echoservo::tune {

// Metric names (TrialResult::metrics keys). All errors are RMS over the scored volumes,
// after TrialRequest::from_s.
namespace metric {
inline constexpr const char* kFoundFraction = "detection.found_fraction";      // 1
inline constexpr const char* kTipRms = "detection.tip_rms_mm";                 // truth
inline constexpr const char* kTargetRms = "detection.target_rms_mm";           // truth
inline constexpr const char* kAxisAngleRms = "detection.axis_angle_rms_rad";   // truth
inline constexpr const char* kPredictionRms = "prediction.rms_mm";             // measurements
inline constexpr const char* kPredictionTruthRms = "prediction.truth_rms_mm";  // truth
inline constexpr const char* kLoopRms = "loop.tip_to_target_rms_mm";  // truth, else measured
inline constexpr const char* kEmRms = "em.tip_to_target_rms_mm";      // EM log
inline constexpr const char* kLatencyP50 = "latency.p50_ms";
inline constexpr const char* kLatencyP99 = "latency.p99_ms";
}  // namespace metric

// Every metric name, in the order above, with its unit and what it needs ("truth", "em",
// or "" for any recording).
struct MetricInfo {
  std::string name, unit, needs, description;
};
const std::vector<MetricInfo>& Metrics();

struct RecordingInfo {
  std::string volumes;  // the sequence file
  std::string em_log;   // empty: none
  std::size_t frames = 0;
  double duration_s = 0.0;
  bool has_truth = false;  // the first frame has truth fields
  bool has_em = false;
};
// Reads headers only (cheap). `em_log` empty: RUN/em.csv when `recording` is a RUN
// directory with one. Throws std::invalid_argument naming the path and why.
RecordingInfo InspectRecording(const std::string& recording, const std::string& em_log = "");
// Whether `info` can give `metric_name`; the reason when not ("needs truth fields, which
// rec.igs.mha lacks").
std::string MetricUnavailableReason(const RecordingInfo& info, std::string_view metric_name);

struct TrialRequest {
  std::string recording;                   // sequence file or RUN directory
  std::string em_log;                      // optional (see InspectRecording)
  std::vector<live::Assignment> settings;  // applied over live::DefaultSettings()
  double latency_s = 0.1;                  // the working latency predictions are scored at, [0, 1]
  double delay_s = -1.0;                   // re-simulated loop: estimate delivered this long after
                                           // acquisition, [0, 1]; < 0: latency_s
  double from_s = 3.0;                     // scores start this long after the first volume, [0, 60]
  std::uint64_t seed = 1;                  // the simulated plant's noise
  bool loop = true;                        // re-simulate the closed loop (the costliest score)
  void Validate() const;                   // throws std::invalid_argument naming the field
};

struct TrialResult {
  std::string status = "ok";  // "ok" or "failed"
  std::string reason;         // why it failed
  std::map<std::string, double> metrics;
  std::size_t volumes = 0, measured = 0, errors = 0;
  // In-process times, s: opening the recording, replaying it (detector + predictor), scoring
  // (truth, prediction, loop, EM).
  double load_s = 0.0, replay_s = 0.0, score_s = 0.0;
  // Why a metric the recording could give is missing (e.g. the EM alignment refused), and
  // other remarks (volumes skipped for non-increasing timestamps).
  std::vector<std::string> notes;
  std::size_t skipped = 0;  // volumes whose timestamp did not increase (not replayed)
};

// What RunTrial saw, per volume and per 10 servo cycles (`tune trial --keep DIR`).
// Positions in the image frame (mm); *_s_mm: axis coordinates (mm); NaN where none.
struct TrialVolumeRow {
  double t_s = 0.0;
  bool found = false, measured = false, has_truth = false;
  bool heartbeat = false;  // the heartbeat model shipped (else a hold)
  std::array<double, 3> tip_mm{}, target_mm{}, axis{};
  std::array<double, 3> truth_tip_mm{}, truth_target_mm{};
  double target_s_mm = 0.0, truth_target_s_mm = 0.0;
  double process_ms = 0.0;
  // The shipped prediction for t_s + latency_s and its references there.
  double predicted_s_mm = 0.0, measured_later_s_mm = 0.0, truth_later_s_mm = 0.0;
};
struct TrialLoopRow {
  double t_s = 0.0, tip_s_mm = 0.0, desired_s_mm = 0.0, base_mm = 0.0;
  std::string mode;
};
struct TrialTrace {
  std::vector<TrialVolumeRow> volumes;
  std::vector<TrialLoopRow> loop;
};

// Replays and scores. Throws std::invalid_argument for a bad request or recording.
TrialResult RunTrial(const TrialRequest& request);
// The same, filling `trace` when not null.
TrialResult RunTrial(const TrialRequest& request, TrialTrace* trace);
// volumes.csv and loop.csv in `dir` (created), crash-safe; throws std::runtime_error.
void WriteTrialTrace(const TrialTrace& trace, const std::filesystem::path& dir);

// JSON (the files of a study, tune/study_files.h; `echoservo tune trial`).
std::string RequestToJson(const TrialRequest& r);
// Throws std::invalid_argument naming `where` and the field.
TrialRequest RequestFromJson(std::string_view json, std::string_view where);
std::string ResultToJson(const TrialResult& r);
TrialResult ResultFromJson(std::string_view json, std::string_view where);

}  // namespace echoservo::tune
