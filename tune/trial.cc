#include "tune/trial.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "estimation/motion_trace.h"
#include "formats/durable_file.h"
#include "formats/em_log.h"
#include "formats/run_record.h"
#include "imaging/io/em_log_import.h"
#include "imaging/io/recording.h"
#include "imaging/io/sequence_reader.h"
#include "imaging/io/truth_fields.h"
#include "link/samples.h"
#include "live/servo_node.h"
#include "live/servo_runtime.h"
#include "live/sim_catheter.h"
#include "live/tracker_node.h"
#include "live/tracker_runtime.h"
#include "live/tracker_source.h"
#include "report/accuracy_report.h"

namespace echoservo::tune {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// The simulated catheter the re-simulated loop drives: the demo's (live/demo_run.h).
constexpr double kTrialSheathIdMm = 1.59;
constexpr double kTrialGuidewireOdMm = 1.50;
// One loop row every this many servo cycles (--keep).
constexpr std::uint64_t kTrialLoopRowEvery = 10;

double TrialSeconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

struct TrialPaths {
  fs::path volumes, em, run_dir;  // run_dir: empty unless a RUN directory with run.json
};

TrialPaths TrialResolve(const std::string& recording, const std::string& em_log) {
  if (recording.empty()) throw std::invalid_argument("recording: no path given");
  std::error_code ec;
  const fs::path p(recording);
  if (!fs::exists(p, ec))
    throw std::invalid_argument("recording " + recording + ": does not exist");
  TrialPaths out;
  if (fs::is_directory(p, ec)) {
    out.volumes = p / "volumes.igs.mhd";
    if (!fs::exists(out.volumes, ec))
      throw std::invalid_argument("recording " + recording +
                                  ": a folder without volumes.igs.mhd (a RUN directory keeps its "
                                  "volumes with `echoservo demo --save-volumes`)");
    if (fs::exists(p / "run.json", ec)) out.run_dir = p;
    if (em_log.empty() && fs::exists(p / "em.csv", ec)) out.em = p / "em.csv";
  } else {
    if (!imaging::IsPlusSequenceFile(p))
      throw std::invalid_argument("recording " + recording +
                                  ": not a PLUS sequence (.igs.mha, .igs.mhd, .igs.nrrd) or a "
                                  "RUN directory");
    out.volumes = p;
  }
  if (!em_log.empty()) {
    if (!fs::exists(em_log, ec))
      throw std::invalid_argument("recording " + recording + ": EM log " + em_log +
                                  " does not exist");
    out.em = em_log;
  }
  return out;
}

std::unique_ptr<imaging::SequenceReader> TrialOpen(const std::string& recording,
                                                   const fs::path& volumes) {
  std::unique_ptr<imaging::SequenceReader> reader;
  try {
    reader = std::make_unique<imaging::SequenceReader>(volumes);
  } catch (const std::exception& e) {
    throw std::invalid_argument("recording " + recording + ": unreadable (" + e.what() + ")");
  }
  const imaging::PlusSequence& seq = reader->sequence();
  if (seq.frames.empty() || seq.FrameBytes() == 0)
    throw std::invalid_argument("recording " + recording +
                                ": holds no image frames (a tracker-only sequence?)");
  return reader;
}

std::optional<imaging::FrameGroundTruth> TrialTruth(const std::string& recording,
                                                    const imaging::SequenceFrame& f,
                                                    std::size_t i) {
  try {
    return imaging::TruthFromFields(f.fields);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("recording " + recording + ": frame " + std::to_string(i) +
                                ": bad truth field: " + e.what());
  }
}

std::array<double, 3> TrialArr(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

double TrialNaN() { return std::numeric_limits<double>::quiet_NaN(); }

struct TrialRms {
  double ss = 0.0;
  std::size_t n = 0;
  void Add(double e) {
    ss += e * e;
    ++n;
  }
  double Value() const { return std::sqrt(ss / static_cast<double>(std::max<std::size_t>(n, 1))); }
};

// A trace of (t, s) for TraceInterpolator; nullopt with fewer than 2 samples.
std::optional<estimation::MotionTrace> TrialTrace2(std::string source, std::vector<double> t,
                                                   std::vector<double> s) {
  if (t.size() < 2) return std::nullopt;
  estimation::MotionTrace m;
  m.source = std::move(source);
  m.t_s = std::move(t);
  m.position_mm = std::move(s);
  return m;
}

// One replayed volume.
struct TrialVolume {
  double t_s = 0.0;     // the tracker's acquisition time: the stamp − scanner.stamp_delay_s
  double true_s = 0.0;  // the real acquisition time: the truth's AcquisitionTime, else t_s
  tracking::CatheterDetection detection;
  bool measured = false, heartbeat = false;
  std::optional<link::TargetEstimateSample> estimate;
  std::optional<imaging::FrameGroundTruth> truth;
  double process_ms = 0.0;
};

}  // namespace

const std::vector<MetricInfo>& Metrics() {
  static const std::vector<MetricInfo> kAll = {
      {metric::kFoundFraction, "1", "", "fraction of volumes with catheter and target detected"},
      {metric::kTipRms, "mm", "truth", "detected tip against the true tip (RMS)"},
      {metric::kTargetRms, "mm", "truth", "detected target against the true target (RMS)"},
      {metric::kAxisAngleRms, "rad", "truth", "detected axis against the true axis (RMS angle)"},
      {metric::kPredictionRms, "mm", "",
       "shipped prediction at +latency against the later measurements (RMS)"},
      {metric::kPredictionTruthRms, "mm", "truth",
       "shipped prediction at +latency against the true target (RMS)"},
      {metric::kLoopRms, "mm", "",
       "re-simulated plant tip against target - standoff (truth, else measured; RMS)"},
      {metric::kEmRms, "mm", "em",
       "EM tip against the replayed targets - standoff, as `echoservo report` (RMS)"},
      {metric::kLatencyP50, "ms", "", "tracker processing time per volume, median"},
      {metric::kLatencyP99, "ms", "", "tracker processing time per volume, 99th percentile"},
  };
  return kAll;
}

RecordingInfo InspectRecording(const std::string& recording, const std::string& em_log) {
  const TrialPaths paths = TrialResolve(recording, em_log);
  const std::unique_ptr<imaging::SequenceReader> reader = TrialOpen(recording, paths.volumes);
  const imaging::PlusSequence& seq = reader->sequence();
  RecordingInfo info;
  info.volumes = paths.volumes.string();
  info.em_log = paths.em.string();
  info.has_em = !paths.em.empty();
  info.frames = seq.frames.size();
  try {
    const std::optional<double> first = seq.frames.front().Timestamp();
    const std::optional<double> last = seq.frames.back().Timestamp();
    if (first && last) info.duration_s = std::max(0.0, *last - *first);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("recording " + recording + ": " + e.what());
  }
  info.has_truth = TrialTruth(recording, seq.frames.front(), 0).has_value();
  return info;
}

std::string MetricUnavailableReason(const RecordingInfo& info, std::string_view metric_name) {
  const auto& all = Metrics();
  const auto it = std::find_if(all.begin(), all.end(),
                               [&](const MetricInfo& m) { return m.name == metric_name; });
  if (it == all.end()) {
    std::string names;
    for (const MetricInfo& m : all) names += (names.empty() ? "" : ", ") + m.name;
    return "unknown metric '" + std::string(metric_name) + "' (known: " + names + ")";
  }
  const std::string file = fs::path(info.volumes).filename().string();
  if (it->needs == "truth" && !info.has_truth)
    return it->name + " needs truth fields (imaging/io/truth_fields.h), which " + file + " lacks";
  if (it->needs == "em" && !info.has_em)
    return it->name + " needs an EM log (a RUN's em.csv, or give one), which " + file + " lacks";
  return "";
}

void TrialRequest::Validate() const {
  auto bad = [](const std::string& field, const std::string& why) {
    throw std::invalid_argument("trial request: " + field + " " + why);
  };
  if (recording.empty()) bad("recording", "is empty");
  if (!(std::isfinite(latency_s) && latency_s >= 0.0 && latency_s <= 1.0))
    bad("latency_s", "must be in [0, 1] s");
  if (!(std::isfinite(delay_s) && delay_s <= 1.0))
    bad("delay_s", "must be in [0, 1] s (or negative: latency_s)");
  if (!(std::isfinite(from_s) && from_s >= 0.0 && from_s <= 60.0))
    bad("from_s", "must be in [0, 60] s");
  for (const live::Assignment& a : settings) {
    try {
      live::CheckValue(live::RequireParameter(a.first), a.second);
    } catch (const std::invalid_argument& e) {
      bad("settings", e.what());
    }
  }
}

namespace {

// Replay: every volume in order through the tracker runtime (no link, no RUN writer), the one
// `track --replay` and `demo` run. Fills the result's counts and timings; `axis`: the node's
// reference axis.
std::vector<TrialVolume> TrialReplay(const TrialRequest& request,
                                     const live::PipelineSettings& settings,
                                     const TrialPaths& paths, Clock::time_point start,
                                     TrialResult& result, std::optional<Eigen::Vector3d>& axis) {
  const std::string& rec = request.recording;
  std::vector<TrialVolume> vols;
  live::TrackerRuntimeOptions ro;
  ro.node = settings.tracker;
  ro.on_tracked = [&](const live::TrackedVolume& r, const live::SourceVolume& v,
                      double process_ms) {
    TrialVolume tv;
    tv.t_s = v.stamp_s - settings.tracker.stamp_delay_s;
    tv.truth = v.truth;
    tv.true_s = tv.truth && tv.truth->acquisition_s ? *tv.truth->acquisition_s : tv.t_s;
    tv.process_ms = process_ms;
    tv.detection = r.detection;
    tv.measured = r.measured;
    tv.heartbeat = r.heartbeat;
    tv.estimate = r.estimate;
    vols.push_back(std::move(tv));
  };
  live::TrackerRuntime runtime(ro);
  std::unique_ptr<live::ReplaySource> source;
  try {
    source = std::make_unique<live::ReplaySource>(paths.volumes);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("recording " + rec + ": unreadable (" + e.what() + ")");
  }
  const auto loaded = Clock::now();
  result.load_s = TrialSeconds(start, loaded);
  const live::TrackerRunResult replay = runtime.Run(*source);
  const live::TrackerNode& node = runtime.node();
  result.skipped = replay.source.skipped;
  if (result.skipped > 0)
    result.notes.push_back(std::to_string(result.skipped) +
                           " volume(s) skipped: timestamp not increasing");
  if (vols.empty())
    throw std::invalid_argument("recording " + rec + ": no volume with an increasing timestamp");
  const auto replayed = Clock::now();
  result.replay_s = TrialSeconds(loaded, replayed);
  result.volumes = vols.size();
  result.measured = node.stats().measured;
  result.errors = node.stats().errors;
  {
    const auto beats =
        std::count_if(vols.begin(), vols.end(), [](const TrialVolume& v) { return v.heartbeat; });
    result.notes.push_back(
        "predictor: the heartbeat model shipped after " + std::to_string(beats) + " of " +
        std::to_string(result.measured) +
        " measured volumes (else a hold); at the end: " + node.heartbeat().reason);
  }
  axis = node.reference_axis();
  return vols;
}

// The scores of one replay (RunTrial): each metric from the replayed volumes, on the real clock
// (the truth's acquisition times where the recording has them): the servo evaluates the shipped
// motion at its own time, so a tracker that takes the stamps of a late-stamping scanner for
// acquisition times (scanner.stamp_delay_s too small) ships a motion shifted in time, and the
// scores against truth show it.
struct TrialScorer {
  const TrialRequest& request;
  const live::PipelineSettings& settings;
  const TrialPaths& paths;
  const std::vector<TrialVolume>& vols;
  const std::optional<Eigen::Vector3d> axis;  // the node's reference axis
  TrialResult& result;
  TrialTrace* trace;
  std::map<std::string, double>& m = result.metrics;
  const std::string& rec = request.recording;
  const double t0 = vols.front().true_s;
  const double from = t0 + request.from_s;
  std::optional<estimation::MotionTrace> measured_trace{}, truth_trace{};
  std::optional<estimation::TraceInterpolator> measured_at{}, truth_at{};

  void FoundAndLatency() {
    m[metric::kFoundFraction] =
        static_cast<double>(std::count_if(
            vols.begin(), vols.end(),
            [](const TrialVolume& v) { return v.detection.found && v.detection.target_found; })) /
        static_cast<double>(vols.size());

    // Latency.
    {
      std::vector<double> ms;
      for (const TrialVolume& v : vols) ms.push_back(v.process_ms);
      m[metric::kLatencyP50] = report::Percentile(ms, 0.5);
      m[metric::kLatencyP99] = report::Percentile(ms, 0.99);
    }
  }

  void Detection() {
    // Detection against the truth fields (found volumes after from_s).
    const bool truth = vols.front().truth.has_value();
    if (truth) {
      TrialRms tip, target, angle;
      for (const TrialVolume& v : vols) {
        if (v.true_s < from || !v.truth || !v.detection.found) continue;
        const imaging::FrameGroundTruth& g = *v.truth;
        if (!g.catheter_visible) continue;
        tip.Add((v.detection.tip_mm - g.tip_mm).norm());
        const double c = std::clamp(
            std::abs(v.detection.axis.direction.normalized().dot(g.axis_direction.normalized())),
            0.0, 1.0);
        angle.Add(std::acos(c));
        if (v.detection.target_found && g.target_visible)
          target.Add((v.detection.target_mm - g.target_mm).norm());
      }
      if (tip.n > 0) {
        m[metric::kTipRms] = tip.Value();
        m[metric::kAxisAngleRms] = angle.Value();
      } else {
        result.notes.push_back("detection: no catheter found after from_s with truth to score");
      }
      if (target.n > 0) m[metric::kTargetRms] = target.Value();
    }
  }

  // Axis coordinates: along the first detection's axis (the node's reference axis).
  void Traces() {
    if (axis) {
      std::vector<double> mt, ms, tt, ts;
      for (const TrialVolume& v : vols) {
        if (v.measured) {
          mt.push_back(v.t_s);
          ms.push_back(v.detection.target_mm.dot(*axis));
        }
        if (v.truth && v.truth->target_visible) {
          tt.push_back(v.true_s);
          ts.push_back(v.truth->target_mm.dot(*axis));
        }
      }
      measured_trace = TrialTrace2(rec + " (measured target)", std::move(mt), std::move(ms));
      truth_trace = TrialTrace2(rec + " (true target)", std::move(tt), std::move(ts));
    }
    if (measured_trace) measured_at.emplace(*measured_trace);
    if (truth_trace) truth_at.emplace(*truth_trace);
  }

  void Rows() {
    if (trace) {
      for (const TrialVolume& v : vols) {
        TrialVolumeRow row;
        row.t_s = v.t_s;
        row.found = v.detection.found && v.detection.target_found;
        row.measured = v.measured;
        row.heartbeat = v.heartbeat;
        row.tip_mm = TrialArr(v.detection.tip_mm);
        row.target_mm = TrialArr(v.detection.target_mm);
        row.axis = TrialArr(v.detection.axis.direction);
        row.has_truth = v.truth.has_value();
        if (v.truth) {
          row.truth_tip_mm = TrialArr(v.truth->tip_mm);
          row.truth_target_mm = TrialArr(v.truth->target_mm);
        }
        row.target_s_mm = axis && v.measured ? v.detection.target_mm.dot(*axis) : TrialNaN();
        row.truth_target_s_mm =
            axis && v.truth && v.truth->target_visible ? v.truth->target_mm.dot(*axis) : TrialNaN();
        row.process_ms = v.process_ms;
        row.predicted_s_mm = row.measured_later_s_mm = row.truth_later_s_mm = TrialNaN();
        trace->volumes.push_back(row);
      }
    }
  }

  void Prediction() {
    // Prediction: the shipped model at t_i + latency against the measurements (and truth).
    {
      TrialRms pm, pt;
      for (std::size_t i = 0; i < vols.size(); ++i) {
        const TrialVolume& v = vols[i];
        if (!v.estimate || !v.measured) continue;
        // Against the measurements: on the tracker's clock (what it can know).
        const double tp = v.t_s + request.latency_s;
        const double pred = v.estimate->motion.Position(tp);
        double ref = 0.0;
        const bool scored = v.true_s >= from;
        if (measured_at && measured_at->At(tp, ref)) {
          if (scored) pm.Add(pred - ref);
          if (trace) trace->volumes[i].measured_later_s_mm = ref;
        }
        // Against the truth: on the real clock, the servo's.
        const double tp_true = v.true_s + request.latency_s;
        if (truth_at && truth_at->At(tp_true, ref)) {
          if (scored) pt.Add(v.estimate->motion.Position(tp_true) - ref);
          if (trace) trace->volumes[i].truth_later_s_mm = ref;
        }
        if (trace) trace->volumes[i].predicted_s_mm = pred;
      }
      if (pm.n > 0) {
        m[metric::kPredictionRms] = pm.Value();
      } else {
        result.notes.push_back(
            "prediction: nothing to score (no estimate after from_s with a measurement latency_s "
            "later)");
      }
      if (pt.n > 0) m[metric::kPredictionTruthRms] = pt.Value();
    }
  }

  void Loop() {
    // The closed loop, re-simulated on the simulated plant at the servo period.
    const std::size_t first_measured = static_cast<std::size_t>(
        std::find_if(vols.begin(), vols.end(), [](const TrialVolume& v) { return v.measured; }) -
        vols.begin());
    if (request.loop && axis && first_measured < vols.size() && (truth_at || measured_at)) {
      live::SimCatheter cat =
          live::MakeSimCatheter(kTrialSheathIdMm, kTrialGuidewireOdMm, request.seed);
      hw::SimulatedCatheter& plant = *cat.plant;
      live::ServoNodeOptions so;
      so.follower = settings.follower;
      so.auto_enable = true;
      live::ServoNode servo(plant, settings.servo, std::move(cat.compensator), so, nullptr);
      const double period = settings.servo.period_s;
      const double delay = request.delay_s < 0.0 ? request.latency_s : request.delay_s;
      std::vector<double> tip_hist;  // the plant's true tip, one per cycle
      auto tip_at = [&](double t) {
        if (tip_hist.empty()) return plant.truth().tip_mm;
        const double k = std::floor((t - t0) / period + 1e-9);
        const std::size_t idx =
            static_cast<std::size_t>(std::clamp(k, 0.0, static_cast<double>(tip_hist.size() - 1)));
        return tip_hist[idx];
      };
      // The imaged tip: the plant's tip plus the first detection's offset (c0).
      const double first_tip_s = vols[first_measured].detection.tip_mm.dot(*axis);
      double c0 = 0.0;
      bool c0_known = false;
      // The score's anchor: the true tip of the first frame, else the first detection.
      const bool truth_anchor = vols.front().truth && vols.front().truth->catheter_visible;
      const double anchor_s = truth_anchor ? vols.front().truth->tip_mm.dot(*axis) : first_tip_s;
      const double anchor_x = plant.truth().tip_mm;  // the plant rests until an estimate arrives
      const std::optional<estimation::TraceInterpolator>& ref_at =
          truth_at ? truth_at : measured_at;
      const double standoff = settings.follower.standoff_mm;
      TrialRms loop;
      // The servo runtime on simulated time, its estimates fed in process after the imaging
      // delay: each one's tip is the plant's at its acquisition, as the image would show it.
      live::DelayedEstimates estimates;
      live::ServoRuntimeOptions sro;
      sro.clock = live::ServoClock::kSimulated;
      sro.t0_s = t0;
      sro.duration_s = std::max(vols.back().true_s - t0, period);
      sro.estimates = &estimates;
      std::size_t next = 0;
      live::ServoRuntime(servo, sro)
          .Run(
              [&](std::uint64_t, double t) {
                while (next < vols.size() && vols[next].true_s + delay <= t + 1e-12) {
                  const TrialVolume& v = vols[next++];
                  if (!v.estimate) continue;
                  const double x_acq = tip_at(v.true_s);
                  if (!c0_known) {
                    c0 = first_tip_s - x_acq;
                    c0_known = true;
                  }
                  link::TargetEstimateSample sample = *v.estimate;
                  sample.publication_time_s = v.true_s + delay;
                  sample.axis = *axis;
                  sample.tip_mm = *axis * (x_acq + c0);
                  estimates.Push(sample, t);
                }
              },
              [&](std::uint64_t k, double t, const live::ServoCycle& c) {
                const double x = plant.truth().tip_mm;
                tip_hist.push_back(x);
                double target_s = 0.0;
                const bool have_ref = ref_at->At(t, target_s);
                const double tip_s = anchor_s + (x - anchor_x);
                if (t >= from && have_ref) loop.Add(tip_s - (target_s - standoff));
                if (trace && k % kTrialLoopRowEvery == 0)
                  trace->loop.push_back({t, tip_s, have_ref ? target_s - standoff : TrialNaN(),
                                         c.record.base_mm,
                                         control::ToString(servo.follower().mode())});
              });
      if (servo.stats().limit_violations > 0)
        result.notes.push_back("loop: " + std::to_string(servo.stats().limit_violations) +
                               " cycle(s) commanded outside a limit");
      if (loop.n > 0) {
        m[metric::kLoopRms] = loop.Value();
      } else {
        result.notes.push_back("loop: nothing to score after from_s");
      }
    } else if (request.loop) {
      result.notes.push_back("loop: not simulated (no volume measured)");
    }
  }

  void Em() {
    // EM: the replayed targets against the recording's EM log, as `echoservo report` does.
    if (!paths.em.empty()) {
      try {
        formats::RunRecord run;
        if (!paths.run_dir.empty()) {
          run = formats::ReadRunRecord(paths.run_dir);
        } else {
          run.dir = paths.volumes.parent_path();
        }
        run.targets.clear();
        for (const TrialVolume& v : vols) {
          formats::TargetRecord r;
          r.acquired_s = r.arrived_s = r.published_s = v.t_s;
          r.found = v.measured;
          if (v.measured) {
            r.target_mm = v.detection.target_mm;
            r.tip_mm = v.detection.tip_mm;
            r.axis = v.detection.axis.direction;
          }
          r.confidence = v.detection.confidence;
          run.targets.push_back(r);
        }
        run.truth.clear();
        run.has_truth = false;  // score the replayed targets, not the live run's truth
        const formats::EmLog em = imaging::ReadEmLog(paths.em, {});
        report::AccuracyOptions ao;
        ao.from_s = from;
        ao.from_reason = "from_s";
        if (const auto& e2i = run.info.meta.em_to_image) {
          ao.alignment.em_to_image = *e2i;
          ao.transform_source = "run.json";
        }
        m[metric::kEmRms] = report::ComputeAccuracy(run, em, ao).rms_mm;
      } catch (const std::invalid_argument& e) {
        result.notes.push_back(std::string("em: not scored: ") + e.what());
      }
    }
  }
};

}  // namespace

TrialResult RunTrial(const TrialRequest& request) { return RunTrial(request, nullptr); }

TrialResult RunTrial(const TrialRequest& request, TrialTrace* trace) {
  request.Validate();
  const auto start = Clock::now();
  const std::string& rec = request.recording;
  const TrialPaths paths = TrialResolve(rec, request.em_log);
  live::PipelineSettings settings = live::DefaultSettings();
  settings.tracker.prediction_latency_s = request.latency_s;  // unless a setting says otherwise
  try {
    live::Apply(request.settings, settings);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("trial settings: ") + e.what());
  }
  TrialResult result;
  std::optional<Eigen::Vector3d> axis;
  const std::vector<TrialVolume> vols = TrialReplay(request, settings, paths, start, result, axis);
  const auto replayed = Clock::now();
  TrialScorer scorer{request, settings, paths, vols, axis, result, trace};
  scorer.FoundAndLatency();
  scorer.Detection();
  scorer.Traces();
  scorer.Rows();
  scorer.Prediction();
  scorer.Loop();
  scorer.Em();
  auto& m = result.metrics;
  for (auto it = m.begin(); it != m.end();)
    it = std::isfinite(it->second) ? std::next(it) : m.erase(it);
  result.score_s = TrialSeconds(replayed, Clock::now());
  return result;
}

void WriteTrialTrace(const TrialTrace& trace, const std::filesystem::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error(dir.string() + ": cannot create (" + ec.message() + ")");
  auto num = [](double x) {
    if (!std::isfinite(x)) return std::string();
    char b[32];
    std::snprintf(b, sizeof b, "%.6g", x);
    return std::string(b);
  };
  auto vec = [&](const std::array<double, 3>& a) {
    return num(a[0]) + "," + num(a[1]) + "," + num(a[2]);
  };
  std::string v =
      "t_s,found,measured,heartbeat,tip_x_mm,tip_y_mm,tip_z_mm,target_x_mm,target_y_mm,target_z_mm,"
      "axis_x,axis_y,axis_z,truth_tip_x_mm,truth_tip_y_mm,truth_tip_z_mm,truth_target_x_mm,"
      "truth_target_y_mm,truth_target_z_mm,target_s_mm,truth_target_s_mm,process_ms,"
      "predicted_s_mm,measured_later_s_mm,truth_later_s_mm\n";
  for (const TrialVolumeRow& r : trace.volumes) {
    v += num(r.t_s) + "," + (r.found ? "1" : "0") + "," + (r.measured ? "1" : "0") + "," +
         (r.heartbeat ? "1" : "0") + "," + vec(r.tip_mm) + "," + vec(r.target_mm) + "," +
         vec(r.axis) + "," +
         (r.has_truth ? vec(r.truth_tip_mm) + "," + vec(r.truth_target_mm) : ",,,,,") + "," +
         num(r.target_s_mm) + "," + num(r.truth_target_s_mm) + "," + num(r.process_ms) + "," +
         num(r.predicted_s_mm) + "," + num(r.measured_later_s_mm) + "," + num(r.truth_later_s_mm) +
         "\n";
  }
  formats::ReplaceFileContents(dir / "volumes.csv", v);
  std::string l = "t_s,tip_s_mm,desired_s_mm,base_mm,mode\n";
  for (const TrialLoopRow& r : trace.loop)
    l += num(r.t_s) + "," + num(r.tip_s_mm) + "," + num(r.desired_s_mm) + "," + num(r.base_mm) +
         "," + r.mode + "\n";
  formats::ReplaceFileContents(dir / "loop.csv", l);
}

// JSON.

std::string RequestToJson(const TrialRequest& r) {
  nlohmann::json settings = nlohmann::json::array();
  for (const live::Assignment& a : r.settings) settings.push_back(live::FormatAssignment(a));
  nlohmann::json j = {{"recording", r.recording}, {"em_log", r.em_log},   {"settings", settings},
                      {"latency_s", r.latency_s}, {"delay_s", r.delay_s}, {"from_s", r.from_s},
                      {"seed", r.seed},           {"loop", r.loop}};
  return j.dump(2);
}

namespace {

nlohmann::json TrialParse(std::string_view json, std::string_view where) {
  nlohmann::json j = nlohmann::json::parse(json, nullptr, false);
  if (j.is_discarded()) throw std::invalid_argument(std::string(where) + ": not valid JSON");
  if (!j.is_object()) throw std::invalid_argument(std::string(where) + ": not a JSON object");
  return j;
}

template <class T>
T TrialField(const nlohmann::json& j, const char* key, std::string_view where, T fallback) {
  if (!j.contains(key)) return fallback;
  try {
    return j.at(key).get<T>();
  } catch (const nlohmann::json::exception&) {
    throw std::invalid_argument(std::string(where) + ": field '" + key + "' has the wrong type");
  }
}

}  // namespace

TrialRequest RequestFromJson(std::string_view json, std::string_view where) {
  const nlohmann::json j = TrialParse(json, where);
  static const char* kKnown[] = {"recording", "em_log", "settings", "latency_s",
                                 "delay_s",   "from_s", "seed",     "loop"};
  for (const auto& item : j.items()) {
    const std::string key = item.key();
    if (std::find_if(std::begin(kKnown), std::end(kKnown),
                     [&](const char* n) { return key == n; }) == std::end(kKnown))
      throw std::invalid_argument(std::string(where) + ": unknown field '" + key + "'");
  }
  TrialRequest r;
  if (!j.contains("recording"))
    throw std::invalid_argument(std::string(where) + ": field 'recording' is missing");
  r.recording = TrialField<std::string>(j, "recording", where, "");
  r.em_log = TrialField<std::string>(j, "em_log", where, "");
  r.latency_s = TrialField<double>(j, "latency_s", where, r.latency_s);
  r.delay_s = TrialField<double>(j, "delay_s", where, r.delay_s);
  r.from_s = TrialField<double>(j, "from_s", where, r.from_s);
  r.seed = TrialField<std::uint64_t>(j, "seed", where, r.seed);
  r.loop = TrialField<bool>(j, "loop", where, r.loop);
  if (j.contains("settings")) {
    const auto texts = TrialField<std::vector<std::string>>(j, "settings", where, {});
    r.settings = live::ParseAssignments(texts, std::string(where) + ": settings");
  }
  try {
    r.Validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string(where) + ": " + e.what());
  }
  return r;
}

std::string ResultToJson(const TrialResult& r) {
  nlohmann::json metrics = nlohmann::json::object();
  for (const auto& [k, v] : r.metrics)
    if (std::isfinite(v)) metrics[k] = v;
  nlohmann::json j = {{"status", r.status},   {"reason", r.reason},     {"metrics", metrics},
                      {"volumes", r.volumes}, {"measured", r.measured}, {"errors", r.errors},
                      {"skipped", r.skipped}, {"load_s", r.load_s},     {"replay_s", r.replay_s},
                      {"score_s", r.score_s}, {"notes", r.notes}};
  return j.dump(2);
}

TrialResult ResultFromJson(std::string_view json, std::string_view where) {
  const nlohmann::json j = TrialParse(json, where);
  TrialResult r;
  r.status = TrialField<std::string>(j, "status", where, "");
  if (r.status != "ok" && r.status != "failed")
    throw std::invalid_argument(std::string(where) +
                                ": field 'status' must be \"ok\" or \"failed\"");
  r.reason = TrialField<std::string>(j, "reason", where, "");
  r.metrics = TrialField<std::map<std::string, double>>(j, "metrics", where, {});
  r.volumes = TrialField<std::size_t>(j, "volumes", where, 0);
  r.measured = TrialField<std::size_t>(j, "measured", where, 0);
  r.errors = TrialField<std::size_t>(j, "errors", where, 0);
  r.skipped = TrialField<std::size_t>(j, "skipped", where, 0);
  r.load_s = TrialField<double>(j, "load_s", where, 0.0);
  r.replay_s = TrialField<double>(j, "replay_s", where, 0.0);
  r.score_s = TrialField<double>(j, "score_s", where, 0.0);
  r.notes = TrialField<std::vector<std::string>>(j, "notes", where, {});
  return r;
}

}  // namespace echoservo::tune
