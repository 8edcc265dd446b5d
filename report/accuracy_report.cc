#include "report/accuracy_report.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <stdexcept>

#include "estimation/harmonic_fit.h"
#include "report/html_page.h"
#include "report/scored_window.h"
#include "report/svg_plot.h"

namespace echoservo::report {
namespace {

using Json = nlohmann::ordered_json;
using html::Fix;
using html::Row;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kGapPeriods = 2.5;      // target interpolation across at most this
constexpr double kDropGapPeriods = 1.5;  // a gap in acquired_s beyond this drops frames
constexpr std::size_t kMaxFitSamples = 1500;
constexpr int kPhaseHarmonics = 3;  // at a known heart rate
constexpr int kMaxSearchHarmonics = 4;
constexpr std::size_t kHistogramBins = 20;
constexpr std::size_t kMaxListedGaps = 20;
constexpr const char* kTipColor = "#0571b0";
constexpr const char* kTargetColor = "#e66101";
constexpr const char* kTrackedColor = "#7b3294";
constexpr const char* kErrorColor = "#222222";
constexpr const char* kSeedColor = "#2e7d32";
constexpr int kHalfWidth = 570;
constexpr const char* kFollowingMode = "following";  // servo.csv: the servo tracks the target

std::string Esc(std::string_view s) { return svg::EscapeHtml(s); }

double Median(std::vector<double> v) { return Percentile(std::move(v), 0.5); }

double Rms(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x * x;
  return v.empty() ? kNaN : std::sqrt(s / static_cast<double>(v.size()));
}

}  // namespace

std::string WindowText(const AccuracyMetrics& m) {
  return Describe(GivenWindow(m.window_from_s, m.window_reason));
}

namespace {

// `field` (tip_mm or target_mm) of the volumes where the target was found, at acquired_s.
PointSeries FoundVolumes(const formats::RunRecord& run,
                         Eigen::Vector3d formats::TargetRecord::*field) {
  PointSeries s;
  for (const formats::TargetRecord& r : run.targets) {
    if (r.found) s.Add(r.acquired_s, r.*field);
  }
  return s;
}

// The target, less the run's standoff along the mean tracked catheter axis (where the tip
// should be) when run.json gives one.
PointSeries TargetSeries(const formats::RunRecord& run) {
  PointSeries s;
  if (!run.has_truth) {
    s = FoundVolumes(run, &formats::TargetRecord::target_mm);
  } else {
    for (const formats::TruthRecord& r : run.truth) s.Add(r.t_s, r.target_mm);
  }
  if (!run.info.standoff_mm || *run.info.standoff_mm == 0.0) return s;
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();
  for (const formats::TargetRecord& r : run.targets)
    if (r.found) axis += r.axis;
  if (!(axis.norm() > 0.0))
    throw std::invalid_argument(
        "report: run.json gives a standoff but targets.csv has no tracked axis");
  axis.normalize();
  for (auto& p : s.p_mm) p -= *run.info.standoff_mm * axis;
  return s;
}

// Unit principal axis of the points, its largest component positive.
Eigen::Vector3d PrincipalAxis(const PointSeries& s) {
  Eigen::Matrix3Xd m(3, s.size());
  for (std::size_t i = 0; i < s.size(); ++i) m.col(static_cast<Eigen::Index>(i)) = s.p_mm[i];
  const Eigen::Matrix3Xd c = m.colwise() - m.rowwise().mean();
  Eigen::Vector3d axis =
      Eigen::JacobiSVD<Eigen::Matrix3Xd>(c, Eigen::ComputeThinU).matrixU().col(0);
  Eigen::Index largest = 0;
  axis.cwiseAbs().maxCoeff(&largest);
  return axis[largest] < 0.0 ? Eigen::Vector3d(-axis) : axis;
}

// The cardiac phase model: cycles(t) = (φ0 + 2π f (t − t0)) / 2π. Fills the metrics' heart
// rate and axis; returns false (with a note) when no fit is possible.
bool FitPhase(const formats::RunRecord& run, const PointSeries& target, const AccuracyOptions& o,
              AccuracyMetrics& m, estimation::FourierMotion& motion) {
  if (target.size() < 2) return false;
  m.motion_axis = PrincipalAxis(target);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : target.p_mm) mean += p;
  mean /= static_cast<double>(target.size());
  const std::size_t stride = (target.size() + kMaxFitSamples - 1) / kMaxFitSamples;
  std::vector<double> t, x;
  for (std::size_t i = 0; i < target.size(); i += stride) {
    t.push_back(target.t_s[i]);
    x.push_back((target.p_mm[i] - mean).dot(m.motion_axis));
  }
  try {
    estimation::HarmonicFit fit;
    if (run.info.heart_rate_hz) {
      fit = estimation::FitHarmonicsAtRate(t.data(), x.data(), t.size(), t.front(),
                                           *run.info.heart_rate_hz, kPhaseHarmonics, 1);
      m.heart_rate_source = "run.json";
    } else {
      estimation::HarmonicFitOptions ho;
      ho.min_rate_hz = o.min_rate_hz;
      ho.max_rate_hz = o.max_rate_hz;
      ho.max_harmonics = kMaxSearchHarmonics;
      fit = estimation::FitHarmonics(t.data(), x.data(), t.size(), t.front(), ho);
      m.heart_rate_source = "target motion";
    }
    motion = fit.motion;
    m.heart_rate_hz = motion.frequency_hz;
    return true;
  } catch (const std::invalid_argument& e) {
    m.heart_rate_source.clear();
    m.notes.push_back(std::string("no heartbeat phase (per-beat and phase errors left out): ") +
                      e.what());
    return false;
  }
}

void BeatAndPhase(const estimation::FourierMotion& motion, int bins, AccuracyMetrics& m) {
  std::map<long, std::vector<double>> by_beat;
  std::map<long, double> beat_start;
  std::vector<std::vector<double>> by_phase(static_cast<std::size_t>(bins));
  for (std::size_t i = 0; i < m.t_s.size(); ++i) {
    const double cycles = (motion.phase0_rad + 2.0 * std::numbers::pi * motion.frequency_hz *
                                                   (m.t_s[i] - motion.t0_s)) /
                          (2.0 * std::numbers::pi);
    const auto beat = static_cast<long>(std::floor(cycles));
    by_beat[beat].push_back(m.error_mm[i]);
    beat_start.try_emplace(beat, m.t_s[i]);
    const auto bin = std::min(bins - 1, static_cast<int>((cycles - std::floor(cycles)) * bins));
    by_phase[static_cast<std::size_t>(bin)].push_back(m.error_mm[i]);
  }
  for (const auto& [beat, errors] : by_beat) {
    m.beats.push_back({beat_start[beat], errors.size(), Rms(errors)});
  }
  for (const auto& errors : by_phase) {
    m.phase_rms_mm.push_back(Rms(errors));
    m.phase_samples.push_back(errors.size());
  }
}

// The scored window (report/scored_window.h): options.from_s when finite, else from the
// first servo.csv row in the following mode (control/target_follower.cc names it "following")
// plus the settling time, else the whole run.
void SetWindow(const formats::RunRecord& run, const AccuracyOptions& o, AccuracyMetrics& m) {
  ScoredWindow w;
  if (std::isfinite(o.from_s)) {
    w = GivenWindow(o.from_s, o.from_reason);
  } else if (!run.has_servo || run.servo.empty()) {
    w = WholeRun("whole run: no servo.csv");
  } else {
    w = WholeRun("whole run: servo.csv has no '" + std::string(kFollowingMode) + "' row");
    for (const formats::ServoRecord& r : run.servo) {
      if (r.mode == kFollowingMode) {
        w = WindowAfterFollowing(r.t_s, run.info.heart_rate_hz);
        break;
      }
    }
  }
  m.window_from_s = w.from_s;
  m.window_reason = w.reason;
}

DroppedFrames CountDropped(const formats::RunRecord& run) {
  DroppedFrames d;
  d.volumes = run.targets.size();
  std::vector<double> dt;
  for (std::size_t i = 0; i < run.targets.size(); ++i) {
    if (!run.targets[i].found) ++d.not_found;
    if (i > 0) dt.push_back(run.targets[i].acquired_s - run.targets[i - 1].acquired_s);
  }
  d.median_period_s = Median(dt);
  for (std::size_t i = 0; i < dt.size(); ++i) {
    if (dt[i] > kDropGapPeriods * d.median_period_s) {
      ++d.gaps;
      d.missing_in_gaps +=
          static_cast<std::size_t>(std::max(1.0, std::round(dt[i] / d.median_period_s) - 1.0));
      d.gap_spans_s.emplace_back(run.targets[i].acquired_s, run.targets[i + 1].acquired_s);
    }
  }
  return d;
}

Json TimingJson(const TimingStats& s) {
  if (s.count == 0) return nullptr;
  return {{"p50", s.p50_ms}, {"p95", s.p95_ms},   {"p99", s.p99_ms},
          {"max", s.max_ms}, {"mean", s.mean_ms}, {"count", s.count}};
}

// ---------------------------------------------------------------------------- HTML

std::string TimingRow(const std::string& name, const TimingStats& s) {
  if (s.count == 0) return Row({name, "&ndash;", "&ndash;", "&ndash;", "&ndash;", "0"});
  return Row({name, Fix(s.p50_ms, 1), Fix(s.p95_ms, 1), Fix(s.p99_ms, 1), Fix(s.max_ms, 1),
              std::to_string(s.count)});
}

std::string SummaryHtml(const AccuracyMetrics& m, const AccuracyReportOptions& o) {
  std::string s = "<section id=\"summary\"><h2>Summary</h2><table>";
  s += Row({"tip-to-target error", "RMS (mm)", "mean (mm)", "p95 (mm)", "max (mm)", "samples"}, "",
           true);
  s += Row({"EM tip vs " + Esc(m.target_source), Fix(m.rms_mm, 3), Fix(m.mean_mm, 3),
            Fix(m.p95_mm, 3), Fix(m.max_mm, 3), std::to_string(m.error_mm.size())});
  s += Row({"seed (Kesner &amp; Howe, trakSTAR)", Fix(o.reference_rms_mm, 2), "", "", "", ""});
  s += "</table><table>";
  s += Row({"timing", "p50 (ms)", "p95 (ms)", "p99 (ms)", "max (ms)", "count"}, "", true);
  s += TimingRow("latency: volume arrived &rarr; setpoint applied", m.latency);
  s += TimingRow("pipeline: volume acquired &rarr; target published", m.pipeline);
  s += "</table><table>";
  s += Row({"frames and samples", "count"}, "", true);
  s += Row({"volumes processed", std::to_string(m.dropped.volumes)});
  s += Row({"dropped frames (not found + missing in gaps)", std::to_string(m.dropped.total())});
  if (m.tracker_volumes) {  // tracker.json: where the dropped frames went
    const formats::TrackerVolumeCounts& t = *m.tracker_volumes;
    s += Row({"volumes acquired by the scanner", std::to_string(t.acquired)});
    s += Row({"acquisitions the scanner missed", std::to_string(t.missed)});
    s += Row({"volumes shed by the tracker (stale: a newer one waiting)", std::to_string(t.shed)});
  }
  s += Row({"EM samples (valid)", std::to_string(m.em.samples.size()) + " (" +
                                      std::to_string(m.em.valid_samples()) + ")"});
  s += Row({"EM drop-outs", std::to_string(m.em.dropouts())});
  s += Row({"servo faults", Fix(m.servo_faults, 0)});
  s += "</table></section>";
  return s;
}

std::string ErrorHtml(const AccuracyMetrics& m) {
  svg::LinePlot err{"Tip-to-target error", "time (s)", "error (mm)", {}, false, kHalfWidth, 320};
  err.lines.push_back({"|EM tip − target|", m.t_s, m.error_mm, kErrorColor, 1.2});
  svg::LinePlot along{"Tip and target along the motion axis",
                      "time (s)",
                      "position (mm)",
                      {},
                      false,
                      kHalfWidth,
                      320};
  std::vector<double> tip, target;
  for (std::size_t i = 0; i < m.t_s.size(); ++i) {
    tip.push_back(m.tip_mm[i].dot(m.motion_axis));
    target.push_back(m.target_mm[i].dot(m.motion_axis));
  }
  along.lines.push_back({"target (" + m.target_source + ")", m.t_s, target, kTargetColor, 1.5});
  along.lines.push_back({"EM tip (image frame)", m.t_s, tip, kTipColor, 1.2});
  return "<section id=\"error\"><h2>Error over time</h2><p class=\"note\">The EM tip mapped "
         "into the image frame (registration and clock offset below) against the target; the "
         "motion axis is the target's principal direction (" +
         Fix(m.motion_axis[0], 3) + ", " + Fix(m.motion_axis[1], 3) + ", " +
         Fix(m.motion_axis[2], 3) + ").</p><div class=\"grid2\"><div>" + svg::RenderLinePlot(err) +
         "</div><div>" + svg::RenderLinePlot(along) + "</div></div></section>";
}

std::string BeatsHtml(const AccuracyMetrics& m, const AccuracyReportOptions& o) {
  std::string s = "<section id=\"beats\"><h2>Per beat and by heartbeat phase</h2>";
  if (m.heart_rate_hz <= 0.0) {
    return s +
           "<p class=\"note\">No heartbeat phase could be fitted (see the notes).</p></section>";
  }
  s += "<p class=\"note\">Heart rate " + Fix(60.0 * m.heart_rate_hz, 1) + " bpm (" +
       Esc(m.heart_rate_source) +
       "); phase 0 is the peak of the target motion's fundamental along its axis.</p>";
  svg::BarChart beats{"Tip-to-target RMS per beat", "RMS (mm)", {}, {}, {}, 3, kHalfWidth, 300};
  svg::BarSeries b{"per beat", {}, kTipColor};
  for (std::size_t i = 0; i < m.beats.size(); ++i) {
    beats.categories.push_back(std::to_string(i + 1));
    b.values.push_back(m.beats[i].rms_mm);
  }
  beats.series.push_back(b);
  beats.references = {
      {"seed " + Fix(o.reference_rms_mm, 2) + " mm", o.reference_rms_mm, kSeedColor},
      {"run " + Fix(m.rms_mm, 2) + " mm", m.rms_mm, "#666666"}};
  svg::BarChart phase{
      "Tip-to-target RMS by heartbeat phase", "RMS (mm)", {}, {}, {}, 3, kHalfWidth, 300};
  svg::BarSeries p{"by phase", m.phase_rms_mm, kTargetColor};
  const auto bins = m.phase_rms_mm.size();
  for (std::size_t i = 0; i < bins; ++i) {
    phase.categories.push_back(std::to_string(100 * i / bins) + "–" +
                               std::to_string(100 * (i + 1) / bins) + "%");
  }
  phase.series.push_back(p);
  s += "<div class=\"grid2\"><div>" + svg::RenderBarChart(beats) + "</div><div>" +
       svg::RenderBarChart(phase) + "</div></div></section>";
  return s;
}

std::string LatencyHtml(const AccuracyMetrics& m) {
  std::string s = "<section id=\"latency\"><h2>Latency</h2>";
  if (m.latency_ms.empty())
    return s + "<p class=\"note\">The run has no latency.csv.</p></section>";
  const double lo = *std::min_element(m.latency_ms.begin(), m.latency_ms.end());
  const double hi = *std::max_element(m.latency_ms.begin(), m.latency_ms.end());
  const double width = std::max(hi - lo, 1e-3) / static_cast<double>(kHistogramBins);
  svg::BarChart hist{
      "Latency distribution (arrived → applied)", "volumes", {}, {}, {}, 0, 1100, 300};
  svg::BarSeries counts{"volumes", std::vector<double>(kHistogramBins, 0.0), kTipColor};
  for (double v : m.latency_ms) {
    const auto bin = std::min(kHistogramBins - 1, static_cast<std::size_t>((v - lo) / width));
    counts.values[bin] += 1.0;
  }
  for (std::size_t i = 0; i < kHistogramBins; ++i) {
    hist.categories.push_back(Fix(lo + width * static_cast<double>(i), 1));
  }
  hist.series.push_back(counts);
  return s + "<p class=\"note\">Bars start at the labelled latency (ms), " + Fix(width, 2) +
         " ms wide.</p>" + svg::RenderBarChart(hist) + "</section>";
}

std::string AlignmentHtml(const AccuracyMetrics& m) {
  const EmAlignment& a = m.alignment;
  std::string s = "<section id=\"alignment\"><h2>EM-to-image alignment</h2><table>";
  s += Row({"quantity", "value"}, "", true);
  s += Row(
      {"clock offset t<sub>image</sub> = t<sub>EM</sub> + offset (s)", Fix(a.em_time_offset_s, 4)});
  if (a.fixed_offset) {
    s += Row({"clock offset", "given, not searched: " + Esc(m.offset_source)});
  } else {
    s += Row({"search window (s)", Fix(a.offset_center_s, 3) + " &plusmn; " +
                                       Fix(a.max_offset_s, 3) + ", step " +
                                       Fix(1000.0 * a.grid_step_s, 2) + " ms"});
  }
  s += Row({"registration residual RMS / max (mm)",
            Fix(a.residual_rms_mm, 3) + " / " + Fix(a.residual_max_mm, 3)});
  s += Row({"pairs (tracked tip, interpolated EM)", std::to_string(a.pairs)});
  s += Row({"rotation angle (deg)", Fix(RotationAngleDeg(a.em_to_image), 3)});
  s +=
      Row({"tracked tip spread, principal SDs (mm)",
           Fix(a.spread_mm[0], 2) + ", " + Fix(a.spread_mm[1], 2) + ", " + Fix(a.spread_mm[2], 2)});
  s += Row({"transform", a.fixed_transform ? "given (" + Esc(m.transform_source) + ")"
                                           : std::string("estimated")});
  s += "</table><p class=\"note\">em_to_image (mm):</p><table>";
  const Eigen::Matrix4d t = a.em_to_image.matrix();
  for (int r = 0; r < 4; ++r) {
    s += Row({Fix(t(r, 0), 6), Fix(t(r, 1), 6), Fix(t(r, 2), 6), Fix(t(r, 3), 3)}, "", false, 0);
  }
  s += "</table>";
  svg::LinePlot grid{"Coarse search: registration RMS by clock offset",
                     "clock offset (s)",
                     "residual RMS (mm)",
                     {},
                     false,
                     1100,
                     280};
  grid.lines.push_back(
      {"closed-form pose at each offset", a.grid_offset_s, a.grid_rms_mm, kTrackedColor, 1.5});
  s += svg::RenderLinePlot(grid);
  s += "<h3>Plausibility checks</h3><table>" +
       Row({"check", "value", "bound", "passed", "why it failed"}, "", true);
  for (const AlignmentCheck& c : m.checks) {
    const bool at_least = c.name == "motion correlation" || c.name == "overlap";
    const std::string unit = c.name == "registration"   ? " mm"
                             : c.name == "clock offset" ? " s"
                                                        : "";
    s += Row({Esc(c.name), Fix(c.value, 3) + unit,
              (at_least ? "&ge; " : "&le; ") + Fix(c.bound, 3) + unit, html::Tag(c.passed),
              Esc(c.message)},
             c.passed ? "" : "sig");
  }
  return s + "</table></section>";
}

std::string EmHtml(const AccuracyMetrics& m, const AccuracyReportOptions& o) {
  const formats::EmLog& e = m.em;
  std::string sensors;
  for (const std::string& n : e.sensors) sensors += (sensors.empty() ? "" : ", ") + Esc(n);
  std::string s = "<section id=\"em\"><h2>EM log</h2><table>";
  s += Row({"file", "<code>" + Esc(o.em_path) + "</code>"});
  s += Row({"format, sensor", std::string(formats::EmLogFormatName(e.format)) + ", " +
                                  Esc(e.sensor) + " (of " + sensors + ")"});
  s += Row({"units in the file", formats::LengthUnitName(e.file_units)});
  s += Row({"samples, valid",
            std::to_string(e.samples.size()) + ", " + std::to_string(e.valid_samples())});
  s += Row({"median period (ms)", Fix(1000.0 * e.MedianPeriodS(), 2)});
  for (const auto& [reason, count] : e.dropouts_by_reason) {
    s += Row({"drop-outs: " + Esc(reason), std::to_string(count)});
  }
  s += "</table>";
  for (const std::string& n : e.notes) s += "<p class=\"note\">" + Esc(n) + "</p>";
  return s + "</section>";
}

std::string FramesHtml(const AccuracyMetrics& m) {
  const DroppedFrames& d = m.dropped;
  std::string s = "<section id=\"frames\"><h2>Dropped frames</h2><p class=\"note\">" +
                  std::to_string(d.not_found) + " of " + std::to_string(d.volumes) +
                  " volumes without a target; " + std::to_string(d.gaps) +
                  " gap(s) longer than 1.5 median periods (" + Fix(1000.0 * d.median_period_s, 1) +
                  " ms) missing " + std::to_string(d.missing_in_gaps) + " volume(s).</p>";
  if (!d.gap_spans_s.empty()) {
    s += "<table>" + Row({"gap from (s)", "to (s)", "length (ms)"}, "", true, 0);
    for (std::size_t i = 0; i < std::min(kMaxListedGaps, d.gap_spans_s.size()); ++i) {
      const auto [from, to] = d.gap_spans_s[i];
      s += Row({Fix(from, 3), Fix(to, 3), Fix(1000.0 * (to - from), 1)}, "", false, 0);
    }
    s += "</table>";
  }
  return s + "</section>";
}

// The servo thread's timing from timing.json (null without one).
Json ServoTimingJson(const AccuracyMetrics& m) {
  if (!m.servo_timing) return Json(nullptr);
  const formats::ServoTimingRecord& t = *m.servo_timing;
  return {{"realtime", t.realtime_summary},
          {"fifo", t.fifo},
          {"refusals", t.refusals},
          {"period_s", t.period_s},
          {"cycles", t.cycles},
          {"overruns", t.overruns},
          {"overrun_fraction", t.overrun_fraction},
          {"max_consecutive_overruns", t.max_consecutive_overruns},
          {"wakeup_latency_us",
           {{"p50", t.wakeup_p50_us},
            {"p99", t.wakeup_p99_us},
            {"p999", t.wakeup_p999_us},
            {"max", t.wakeup_max_us}}},
          {"cycle_duration_us",
           {{"p50", t.cycle_p50_us},
            {"p99", t.cycle_p99_us},
            {"p999", t.cycle_p999_us},
            {"max", t.cycle_max_us}}},
          {"deadline_holds", t.deadline_holds},
          {"deadline_retracts", t.deadline_retracts}};
}

std::string ServoTimingHtml(const AccuracyMetrics& m) {
  if (!m.servo_timing) return "";
  const formats::ServoTimingRecord& t = *m.servo_timing;
  std::string s = "<section id=\"servo-timing\"><h2>Servo timing</h2><p class=\"note\">" +
                  Esc(t.realtime_summary) + "; " + std::to_string(t.cycles) + " cycles of " +
                  Fix(1e3 * t.period_s, 2) + " ms, " + std::to_string(t.overruns) +
                  " overrun(s) (" + Fix(100.0 * t.overrun_fraction, 3) + " %), at most " +
                  std::to_string(t.max_consecutive_overruns) + " in a row; deadline holds " +
                  std::to_string(t.deadline_holds) + ", retractions " +
                  std::to_string(t.deadline_retracts) + ".</p><table>" +
                  Row({"µs", "p50", "p99", "p99.9", "max"}, "", true, 0) +
                  Row({"wake-up latency", Fix(t.wakeup_p50_us, 0), Fix(t.wakeup_p99_us, 0),
                       Fix(t.wakeup_p999_us, 0), Fix(t.wakeup_max_us, 0)},
                      "", false, 0) +
                  Row({"cycle duration", Fix(t.cycle_p50_us, 0), Fix(t.cycle_p99_us, 0),
                       Fix(t.cycle_p999_us, 0), Fix(t.cycle_max_us, 0)},
                      "", false, 0) +
                  "</table>";
  for (const std::string& r : t.refusals) s += "<p class=\"note\">" + Esc(r) + "</p>";
  return s + "</section>";
}

std::string ServoHtml(const formats::RunRecord& run, const AccuracyMetrics& m) {
  if (!run.has_servo) return "";
  std::vector<double> t, setpoint, base, tip;
  for (const formats::ServoRecord& r : run.servo) {
    t.push_back(r.t_s);
    setpoint.push_back(r.setpoint_mm);
    base.push_back(r.base_mm);
    tip.push_back(r.tip_estimate_mm);
  }
  svg::LinePlot p{"Servo", "time (s)", "position along the catheter (mm)", {}, false, 1100, 300};
  p.lines.push_back({"setpoint", t, setpoint, kTargetColor, 1.5});
  p.lines.push_back({"tip estimate", t, tip, kTipColor, 1.2});
  p.lines.push_back({"base", t, base, "#a0a0a0", 1.0});
  std::string s =
      "<section id=\"servo\"><h2>Servo</h2><table>" + Row({"mode", "time (s)"}, "", true);
  for (const auto& [mode, seconds] : m.servo_mode_s) s += Row({Esc(mode), Fix(seconds, 2)});
  s += Row({"faults during the run", Fix(m.servo_faults, 0)}) + "</table>";
  return s + svg::RenderLinePlot(p) + "</section>";
}

}  // namespace

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return kNaN;
  std::sort(values.begin(), values.end());
  const double pos = std::clamp(p, 0.0, 1.0) * static_cast<double>(values.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, values.size() - 1);
  return values[lo] + (pos - static_cast<double>(lo)) * (values[hi] - values[lo]);
}

TimingStats SummarizeMs(const std::vector<double>& v) {
  TimingStats s;
  s.count = v.size();
  if (v.empty()) return s;
  s.p50_ms = Percentile(v, 0.50);
  s.p95_ms = Percentile(v, 0.95);
  s.p99_ms = Percentile(v, 0.99);
  s.max_ms = *std::max_element(v.begin(), v.end());
  double sum = 0.0;
  for (double x : v) sum += x;
  s.mean_ms = sum / static_cast<double>(v.size());
  return s;
}

AccuracyMetrics ComputeAccuracy(const formats::RunRecord& run, const formats::EmLog& em,
                                const AccuracyOptions& o) {
  if (o.phase_bins < 1) throw std::invalid_argument("accuracy: phase_bins must be at least 1");
  AccuracyMetrics m;
  m.em = em;
  const PointSeries em_points = ValidEmPoints(em);
  const PointSeries image_tip = FoundVolumes(run, &formats::TargetRecord::tip_mm);
  m.alignment = AlignEmToImage(em_points, image_tip, o.alignment);
  m.transform_source = m.alignment.fixed_transform ? o.transform_source : "estimated";
  m.offset_source = m.alignment.fixed_offset ? o.offset_source : "estimated";
  if (m.alignment.fixed_offset) m.tracker_lag_s = o.tracker_lag_s;
  // Every alignment, estimated or given, must show that the log belongs to this run before
  // a figure is given.
  m.checks = CheckAlignment(em_points, image_tip, m.alignment, o.checks);
  std::string failed;
  for (const AlignmentCheck& c : m.checks) {
    if (c.passed) continue;
    m.warnings.push_back(c.message);
    failed += "; " + c.message;
  }
  if (!m.warnings.empty()) {
    if (!o.force) {
      throw std::invalid_argument(
          "EM log refused: " + failed.substr(2) +
          ". (--force gives the figures anyway, marked as not trustworthy)");
    }
    m.forced = true;
  }
  SetWindow(run, o, m);
  const PointSeries target = TargetSeries(run);
  m.target_source = run.has_truth ? "truth.csv" : "targets.csv";
  const double target_gap = kGapPeriods * target.MedianPeriodS();
  for (std::size_t i = 0; i < em_points.size(); ++i) {
    const double t = em_points.t_s[i] + m.alignment.em_time_offset_s;
    if (t < m.window_from_s) continue;
    const auto goal = target.At(t, target_gap);
    if (!goal) continue;
    const Eigen::Vector3d tip = m.alignment.em_to_image * em_points.p_mm[i];
    m.t_s.push_back(t);
    m.tip_mm.push_back(tip);
    m.target_mm.push_back(*goal);
    m.error_mm.push_back((tip - *goal).norm());
  }
  if (m.error_mm.empty()) {
    std::string span = "no valid EM sample";
    if (!em_points.t_s.empty()) {
      span = "the EM log covers " + Fix(em_points.t_s.front() + m.alignment.em_time_offset_s, 2) +
             "–" + Fix(em_points.t_s.back() + m.alignment.em_time_offset_s, 2) + " s";
    }
    throw std::invalid_argument(
        "accuracy: no valid EM sample falls within the target series (" + m.target_source + ", " +
        Fix(target.t_s.empty() ? kNaN : target.t_s.front(), 2) + "–" +
        Fix(target.t_s.empty() ? kNaN : target.t_s.back(), 2) + " s) after the clock offset of " +
        Fix(m.alignment.em_time_offset_s, 3) + " s in the window " + WindowText(m) + "; " + span +
        " (--from moves the window's start)");
  }
  m.rms_mm = Rms(m.error_mm);
  double sum = 0.0;
  for (double e : m.error_mm) sum += e;
  m.mean_mm = sum / static_cast<double>(m.error_mm.size());
  m.p95_mm = Percentile(m.error_mm, 0.95);
  m.max_mm = *std::max_element(m.error_mm.begin(), m.error_mm.end());

  estimation::FourierMotion motion;
  if (FitPhase(run, target, o, m, motion)) BeatAndPhase(motion, o.phase_bins, m);

  for (const formats::LatencyRecord& r : run.latency)
    m.latency_ms.push_back(1000.0 * (r.applied_s - r.arrived_s));
  m.latency = SummarizeMs(m.latency_ms);
  std::vector<double> pipeline;
  for (const formats::TargetRecord& r : run.targets)
    pipeline.push_back(1000.0 * (r.published_s - r.acquired_s));
  m.pipeline = SummarizeMs(pipeline);
  m.dropped = CountDropped(run);
  if (run.has_timing) m.servo_timing = run.timing;
  if (run.has_tracker_counts) m.tracker_volumes = run.tracker;
  if (!run.servo.empty()) {
    m.servo_faults = run.servo.back().faults - run.servo.front().faults;
    for (std::size_t i = 0; i + 1 < run.servo.size(); ++i) {
      m.servo_mode_s[run.servo[i].mode] += run.servo[i + 1].t_s - run.servo[i].t_s;
    }
  }
  if (!run.has_latency) m.notes.push_back("the run has no latency.csv: no latency figures");
  return m;
}

std::string AccuracyJson(const AccuracyMetrics& m, const AccuracyReportOptions& o) {
  Json beats = Json::array(), per_beat = Json::array();
  for (const BeatError& b : m.beats) {
    per_beat.push_back(b.rms_mm);
    beats.push_back({{"start_s", b.start_s}, {"samples", b.samples}, {"rms_mm", b.rms_mm}});
  }
  Json transform = Json::array();
  const Eigen::Matrix4d t = m.alignment.em_to_image.matrix();
  for (int r = 0; r < 4; ++r) transform.push_back({t(r, 0), t(r, 1), t(r, 2), t(r, 3)});
  Json dropouts = Json::object();
  for (const auto& [reason, count] : m.em.dropouts_by_reason) dropouts[reason] = count;
  Json modes = Json::object();
  for (const auto& [mode, seconds] : m.servo_mode_s) modes[mode] = seconds;
  Json checks = Json::array();
  for (const AlignmentCheck& c : m.checks) {
    checks.push_back({{"name", c.name},
                      {"value", c.value},
                      {"bound", c.bound},
                      {"passed", c.passed},
                      {"message", c.message}});
  }
  const Json j = {
      {"run", o.run_path},
      {"em_log", o.em_path},
      {"em_format", formats::EmLogFormatName(m.em.format)},
      {"em_sensor", m.em.sensor},
      {"target_source", m.target_source},
      {"tip_to_target_rms_mm", m.rms_mm},
      {"tip_to_target_mean_mm", m.mean_mm},
      {"tip_to_target_p95_mm", m.p95_mm},
      {"tip_to_target_max_mm", m.max_mm},
      {"evaluated_samples", m.error_mm.size()},
      {"reference_rms_mm", o.reference_rms_mm},
      {"heart_rate_hz", m.heart_rate_hz > 0.0 ? Json(m.heart_rate_hz) : Json(nullptr)},
      {"heart_rate_source", m.heart_rate_source},
      {"per_beat_rms_mm", per_beat},
      {"beats", beats},
      {"phase_rms_mm", m.phase_rms_mm},
      {"phase_samples", m.phase_samples},
      {"latency_ms", TimingJson(m.latency)},
      {"pipeline_latency_ms", TimingJson(m.pipeline)},
      {"dropped_frames", m.dropped.total()},
      {"dropped",
       {{"volumes", m.dropped.volumes},
        {"not_found", m.dropped.not_found},
        {"gaps", m.dropped.gaps},
        {"missing_in_gaps", m.dropped.missing_in_gaps},
        {"median_period_s", m.dropped.median_period_s}}},
      {"em_time_offset_s", m.alignment.em_time_offset_s},
      {"em_time_offset_source", m.offset_source},
      {"tracker_lag_s", std::isfinite(m.tracker_lag_s) ? Json(m.tracker_lag_s) : Json(nullptr)},
      {"registration_rms_mm", m.alignment.residual_rms_mm},
      {"registration_max_mm", m.alignment.residual_max_mm},
      {"registration_pairs", m.alignment.pairs},
      {"em_to_image", transform},
      {"em_to_image_rotation_deg", RotationAngleDeg(m.alignment.em_to_image)},
      {"em_to_image_given", m.alignment.fixed_transform},
      {"em_to_image_source", m.transform_source},
      {"window",
       {{"from_s", std::isfinite(m.window_from_s) ? Json(m.window_from_s) : Json(nullptr)},
        {"reason", m.window_reason},
        {"text", WindowText(m)}}},
      {"checks", checks},
      {"forced", m.forced},
      {"warnings", m.warnings},
      {"em_samples", m.em.samples.size()},
      {"em_valid_samples", m.em.valid_samples()},
      {"em_dropouts", m.em.dropouts()},
      {"em_dropouts_by_reason", dropouts},
      {"servo_faults", m.servo_faults},
      {"servo_mode_s", modes},
      {"servo_timing", ServoTimingJson(m)},
      {"tracker_volumes", m.tracker_volumes
                              ? Json::parse(formats::TrackerCountsJson(*m.tracker_volumes))
                              : Json(nullptr)},
      {"notes", m.notes}};
  return j.dump(2);
}

std::string RenderAccuracyReport(const formats::RunRecord& run, const AccuracyMetrics& m,
                                 const AccuracyReportOptions& o) {
  const double duration = m.t_s.empty() ? 0.0 : m.t_s.back() - m.t_s.front();
  const std::vector<std::pair<std::string, std::string>> facts = {
      {"Run", "<code>" + Esc(o.run_path) + "</code>"},
      {"EM log", "<code>" + Esc(o.em_path) + "</code> (" + formats::EmLogFormatName(m.em.format) +
                     ", sensor " + Esc(m.em.sensor) + ")"},
      {"Tip-to-target RMS",
       "<b>" + Fix(m.rms_mm, 3) + " mm</b> (seed " + Fix(o.reference_rms_mm, 2) + " mm)"},
      {"Target", Esc(m.target_source) + (run.has_truth ? " (simulation truth)" : " (tracked)")},
      {"Heart rate", m.heart_rate_hz > 0.0 ? Fix(60.0 * m.heart_rate_hz, 1) + " bpm (" +
                                                 Esc(m.heart_rate_source) + ")"
                                           : std::string("&ndash;")},
      {"Evaluated",
       std::to_string(m.error_mm.size()) + " EM samples over " + Fix(duration, 1) + " s"},
      {"Window", Esc(WindowText(m))},
      {"EM&rarr;image transform", Esc(m.transform_source)},
      {"EM clock offset", Fix(m.alignment.em_time_offset_s, 4) + " s (" +
                              Esc(m.alignment.fixed_offset ? "tracker lag " + m.offset_source
                                                           : std::string("estimated")) +
                              ")"},
      {"Generated", Esc(o.generated.empty() ? html::NowUtc() : o.generated)},
  };
  std::string page = html::PageStart("Accuracy report: " + Esc(o.run_path));
  page += html::TopHeader("Accuracy report",
                          "echoservo &middot; the catheter tip measured by the EM tracker against "
                          "the target, and the pipeline's timing",
                          facts);
  if (m.forced) {
    page +=
        "<div class=\"verdict miss\" id=\"forced\"><b>Warning: figures forced (--force).</b> "
        "The EM log failed the plausibility checks below, so these figures may not measure "
        "this run:<ol class=\"evidence\">";
    for (const std::string& w : m.warnings) page += "<li>" + Esc(w) + "</li>";
    page += "</ol></div>\n";
  }
  page +=
      "<nav class=\"toc\"><a href=\"#summary\">Summary</a><a href=\"#error\">Error over time</a>"
      "<a href=\"#beats\">Per beat and phase</a><a href=\"#latency\">Latency</a><a "
      "href=\"#alignment\">Alignment</a><a href=\"#em\">EM log</a><a href=\"#frames\">Dropped "
      "frames</a></nav>\n";
  page += SummaryHtml(m, o) + "\n";
  page += ErrorHtml(m) + "\n";
  page += BeatsHtml(m, o) + "\n";
  page += LatencyHtml(m) + "\n";
  page += AlignmentHtml(m) + "\n";
  page += EmHtml(m, o) + "\n";
  page += FramesHtml(m) + "\n";
  page += ServoHtml(run, m) + "\n";
  page += ServoTimingHtml(m) + "\n";
  if (!m.notes.empty()) {
    page += "<section id=\"notes\"><h2>Notes</h2><ul>";
    for (const std::string& n : m.notes) page += "<li>" + Esc(n) + "</li>";
    page += "</ul></section>\n";
  }
  page +=
      "<footer>Generated by <code>echoservo report</code>. Self-contained page: no external "
      "resources.</footer></main></body></html>\n";
  return page;
}

}  // namespace echoservo::report
