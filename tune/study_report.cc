#include "tune/study_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "live/pipeline_parameters.h"
#include "report/html_page.h"
#include "report/svg_plot.h"
#include "tune/study_files.h"
#include "tune/study_stats.h"
#include "tune/trial.h"

namespace echoservo::tune {
namespace {

namespace fs = std::filesystem;
namespace html = report::html;
namespace svg = report::svg;
using Json = nlohmann::json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kSignificance = 0.05;            // the p-value a set must beat (with its interval)
constexpr std::size_t kMaxRankedRows = 60;        // HTML ranking table; JSON has every set
constexpr std::size_t kMaxCommandRecordings = 8;  // replay commands listed per recording
constexpr std::size_t kMarksPerLine = 600;        // scatter marks per polyline group
// Recordings' colours: no green or red, which mark the default and the best set.
constexpr const char* kPalette[] = {"#1f77b4", "#ff7f0e", "#9467bd", "#8c564b",
                                    "#e377c2", "#17becf", "#bcbd22", "#7f7f7f"};
constexpr std::size_t kPaletteSize = sizeof kPalette / sizeof kPalette[0];

// One trial as the report sees it.
struct StudyReportCell {
  bool present = false;  // a request.json exists
  double value = kNaN;   // the objective, finite when finished with it
  std::string state;     // "ok", "failed", "pending"
  std::string reason;    // why failed / pending
  std::string id;
};

struct StudyReportSet {
  int index = 0;
  std::vector<live::Assignment> settings;  // as in its requests
  std::vector<StudyReportCell> cells;      // per recording
  std::size_t finished = 0, failed = 0, pending = 0;
  bool complete = false;  // every recording finished with a finite objective
  double mean = kNaN;     // over the finished recordings
  PairedComparison paired;
  bool better = false;                  // beats the default beyond noise
  std::optional<TrialRequest> request;  // one of its requests (for the replay commands)
};

struct StudyReportFailure {
  std::string id;
  int set = 0, recording = 0;
  std::string reason;
};

struct StudyReportData {
  fs::path study;
  StudyHeader header;
  StudyReportOptions options;
  std::string unit;
  std::vector<std::string> names;    // recording short names
  std::vector<StudyReportSet> sets;  // by set index (gaps skipped)
  std::vector<StudyReportFailure> failures;
  std::vector<std::string> problems;
  std::size_t trials = 0, finished = 0, failed = 0, pending = 0;
  int best = -1;         // position in `sets`, -1: none complete
  int default_pos = -1;  // position of set 0 in `sets`
};

bool StudyReportBetter(double a, double b, bool minimize) { return minimize ? a < b : a > b; }

std::string StudyReportOutcomeReason(const TaskOutcome& o) {
  if (!o.error.empty()) return o.error;
  char buf[160];
  if (o.timed_out) {
    std::snprintf(buf, sizeof buf, "timed out after %.1f s (killed)", o.wall_s);
    return buf;
  }
  if (o.signal != 0) return "killed by signal " + std::to_string(o.signal);
  if (o.exit_code != 0) return "exit status " + std::to_string(o.exit_code) + ", no result.json";
  return "exited 0 without writing result.json";
}

double StudyReportValue(const std::vector<live::Assignment>& settings, const std::string& name) {
  double v = kNaN;
  bool found = false;
  for (const live::Assignment& a : settings) {
    if (a.first == name) v = a.second, found = true;  // the last one wins, as Apply does
  }
  if (found) return v;
  if (live::FindParameter(name) == nullptr) return kNaN;
  try {
    return live::Get(live::DefaultSettings(), name);
  } catch (const std::exception&) {
    return kNaN;
  }
}

std::string StudyReportAssignments(const std::vector<live::Assignment>& settings) {
  std::string s;
  for (const live::Assignment& a : settings) {
    if (!s.empty()) s += ' ';
    s += live::FormatAssignment(a);
  }
  return s;
}

// Shell word: quoted only where needed.
std::string StudyReportShell(const std::string& word) {
  if (!word.empty() && word.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                              "0123456789_-./=:,+@%") == std::string::npos)
    return word;
  std::string out = "'";
  for (char c : word) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string StudyReportNumber(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// The two commands that replay `set`'s settings on `request`'s recording by hand.
std::vector<std::string> StudyReportCommands(const std::vector<live::Assignment>& settings,
                                             const TrialRequest& r) {
  std::string sets;
  for (const live::Assignment& a : settings)
    sets += " --set " + StudyReportShell(live::FormatAssignment(a));
  std::string trial = "echoservo tune trial --recording " + StudyReportShell(r.recording);
  if (!r.em_log.empty()) trial += " --em " + StudyReportShell(r.em_log);
  trial += sets + " --latency " + StudyReportNumber(r.latency_s);
  if (r.delay_s >= 0.0) trial += " --delay " + StudyReportNumber(r.delay_s);
  trial += " --from " + StudyReportNumber(r.from_s) + " --seed " + std::to_string(r.seed);
  if (!r.loop) trial += " --no-loop";
  std::error_code ec;
  std::string volumes = r.recording;
  if (fs::is_directory(r.recording, ec))
    volumes = (fs::path(r.recording) / "volumes.igs.mhd").string();
  const std::string track = "echoservo track --replay " + StudyReportShell(volumes) + sets;
  return {trial, track};
}

StudyReportData StudyReportAnalyze(const fs::path& study, const StudyReportOptions& o) {
  if (o.bootstrap_samples < 100 || o.bootstrap_samples > 1000000)
    throw std::invalid_argument("study report: bootstrap samples " +
                                std::to_string(o.bootstrap_samples) + " outside [100, 1000000]");
  if (!(o.confidence > 0.0 && o.confidence < 1.0))
    throw std::invalid_argument("study report: confidence outside (0, 1)");
  StudyReportData d;
  d.study = study;
  d.options = o;
  d.header = ReadStudyHeader(study);
  for (const MetricInfo& m : Metrics()) {
    if (m.name == d.header.objective) d.unit = m.unit;
  }
  const std::vector<StudyTrial> trials = ReadTrials(study, &d.problems);
  int recordings = static_cast<int>(d.header.recordings.size());
  for (const StudyTrial& t : trials) recordings = std::max(recordings, t.recording_index + 1);
  for (int r = 0; r < recordings; ++r) {
    std::string name;
    if (static_cast<std::size_t>(r) < d.header.recording_names.size())
      name = d.header.recording_names[static_cast<std::size_t>(r)];
    if (name.empty() && static_cast<std::size_t>(r) < d.header.recordings.size())
      name = fs::path(d.header.recordings[static_cast<std::size_t>(r)]).filename().string();
    if (name.empty()) name = "r" + std::to_string(r);
    d.names.push_back(name);
  }

  std::map<int, StudyReportSet> sets;
  for (const StudyTrial& t : trials) {
    StudyReportSet& s = sets[t.set_index];
    if (s.cells.empty()) {
      s.index = t.set_index;
      s.cells.resize(static_cast<std::size_t>(recordings));
      s.settings = t.request.settings;
      s.request = t.request;
    }
    StudyReportCell& c = s.cells[static_cast<std::size_t>(t.recording_index)];
    if (c.present) {
      d.problems.push_back("trial " + t.id + ": a second trial for set " +
                           std::to_string(t.set_index) + ", recording " +
                           std::to_string(t.recording_index) + " (ignored)");
      continue;
    }
    c.present = true;
    c.id = t.id;
    ++d.trials;
    if (t.result) {
      const TrialResult& r = *t.result;
      if (r.status != "ok") {
        c.state = "failed";
        c.reason = r.reason.empty() ? "failed (no reason given)" : r.reason;
      } else {
        const auto it = r.metrics.find(d.header.objective);
        if (it == r.metrics.end()) {
          c.state = "failed";
          c.reason = "result.json has no " + d.header.objective;
        } else if (!std::isfinite(it->second)) {
          c.state = "failed";
          c.reason = d.header.objective + " is not finite";
        } else {
          c.state = "ok";
          c.value = it->second;
        }
      }
    } else if (std::error_code ec; fs::exists(TrialDir(study, t.id) / "result.json", ec)) {
      c.state = "failed";
      c.reason = "result.json unreadable (see the problems below)";
    } else if (t.outcome) {
      c.state = "failed";
      c.reason = StudyReportOutcomeReason(*t.outcome);
    } else {
      c.state = "pending";
      c.reason = "not run yet";
    }
    if (c.state == "ok") {
      ++s.finished, ++d.finished;
    } else if (c.state == "failed") {
      ++s.failed, ++d.failed;
      d.failures.push_back({t.id, t.set_index, t.recording_index, c.reason});
    } else {
      ++s.pending, ++d.pending;
    }
  }
  if (d.finished == 0) {
    std::string example;
    if (!d.failures.empty())
      example = "; " + d.failures.front().id + ": " + d.failures.front().reason;
    throw std::invalid_argument(study.string() + ": no trial with a value of " +
                                d.header.objective + " yet (" + std::to_string(d.trials) +
                                " trials: " + std::to_string(d.failed) + " failed, " +
                                std::to_string(d.pending) + " not run" + example + ")");
  }
  for (auto& [index, s] : sets) {
    double sum = 0.0;
    for (const StudyReportCell& c : s.cells) {
      if (c.state == "ok") sum += c.value;
    }
    if (s.finished > 0) s.mean = sum / static_cast<double>(s.finished);
    s.complete = s.finished == static_cast<std::size_t>(recordings);
    d.sets.push_back(std::move(s));
  }
  for (std::size_t i = 0; i < d.sets.size(); ++i) {
    if (d.sets[i].index == 0) d.default_pos = static_cast<int>(i);
  }
  // Paired against the default on the recordings where both finished.
  if (d.default_pos >= 0) {
    const StudyReportSet& def = d.sets[static_cast<std::size_t>(d.default_pos)];
    for (StudyReportSet& s : d.sets) {
      std::vector<double> diff;
      for (std::size_t r = 0; r < s.cells.size(); ++r) {
        if (s.cells[r].state == "ok" && def.cells[r].state == "ok")
          diff.push_back(s.cells[r].value - def.cells[r].value);
      }
      // Each set its own random stream, so adding a set does not move the others' figures.
      const std::uint64_t seed =
          o.seed + 0x9e3779b97f4a7c15ULL * static_cast<std::uint64_t>(s.index);
      s.paired = ComparePaired(diff, o.bootstrap_samples, o.confidence, seed);
      if (s.index != 0 && s.paired.meaningful) {
        const bool ci_clear = d.header.minimize ? s.paired.ci_high < 0.0 : s.paired.ci_low > 0.0;
        s.better = ci_clear && s.paired.p_value < kSignificance;
      }
    }
  }
  for (std::size_t i = 0; i < d.sets.size(); ++i) {
    const StudyReportSet& s = d.sets[i];
    if (!s.complete) continue;
    if (d.best < 0 ||
        StudyReportBetter(s.mean, d.sets[static_cast<std::size_t>(d.best)].mean, d.header.minimize))
      d.best = static_cast<int>(i);
  }
  std::sort(d.failures.begin(), d.failures.end(),
            [](const StudyReportFailure& a, const StudyReportFailure& b) { return a.id < b.id; });
  return d;
}

// Positions in d.sets, best first: complete sets by mean, then incomplete ones by mean.
std::vector<std::size_t> StudyReportRanking(const StudyReportData& d) {
  std::vector<std::size_t> order(d.sets.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const StudyReportSet& x = d.sets[a];
    const StudyReportSet& y = d.sets[b];
    if (x.complete != y.complete) return x.complete;
    const bool fx = std::isfinite(x.mean), fy = std::isfinite(y.mean);
    if (fx != fy) return fx;
    if (!fx) return false;
    return StudyReportBetter(x.mean, y.mean, d.header.minimize);
  });
  return order;
}

// The verdict on the best set against the default, in words.
std::string StudyReportVerdict(const StudyReportData& d) {
  if (d.best < 0) return "No parameter set finished on every recording, so none is called best.";
  const StudyReportSet& b = d.sets[static_cast<std::size_t>(d.best)];
  if (d.default_pos < 0)
    return "Set " + std::to_string(b.index) +
           " has the best mean, but the default settings (set 0) have no trial to compare with.";
  if (b.index == 0) return "The default settings (set 0) have the best mean objective.";
  const PairedComparison& p = b.paired;
  if (!p.meaningful) {
    return "Set " + std::to_string(b.index) + " has the best mean objective, but with " +
           std::to_string(p.n) +
           " recording(s) paired with the default no confidence interval "
           "or test is meaningful (at least " +
           std::to_string(kMinPairedRecordings) +
           " needed): it is not shown to be better than the default.";
  }
  if (b.better) {
    return "Set " + std::to_string(b.index) + " beats the default beyond noise: " +
           "its confidence interval of the difference excludes 0 and p = " +
           html::Sig(p.p_value, 3) + " < " + html::Fix(kSignificance, 2) + ".";
  }
  return "Set " + std::to_string(b.index) + " has the best mean objective, but the difference " +
         "from the default is within noise (" +
         (d.header.minimize ? (p.ci_high < 0.0 ? "interval excludes 0" : "interval includes 0")
                            : (p.ci_low > 0.0 ? "interval excludes 0" : "interval includes 0")) +
         ", p = " + html::Sig(p.p_value, 3) + "): it is not shown to be better than the default.";
}

Json StudyReportNumberJson(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

Json StudyReportSettingsJson(const std::vector<live::Assignment>& settings) {
  Json j = Json::object();
  for (const live::Assignment& a : settings) j[a.first] = a.second;
  return j;
}

Json StudyReportPairedJson(const PairedComparison& p) {
  return {{"n", p.n},
          {"mean_difference", StudyReportNumberJson(p.mean_difference)},
          {"ci_low", StudyReportNumberJson(p.ci_low)},
          {"ci_high", StudyReportNumberJson(p.ci_high)},
          {"p_value", StudyReportNumberJson(p.p_value)},
          {"p_exact", p.meaningful ? Json(p.exact) : Json(nullptr)},
          {"meaningful", p.meaningful}};
}

Json StudyReportToJson(const StudyReportData& d) {
  const bool minimize = d.header.minimize;
  Json recordings = Json::array();
  for (std::size_t r = 0; r < d.names.size(); ++r) {
    recordings.push_back(
        {{"index", r},
         {"name", d.names[r]},
         {"path", r < d.header.recordings.size() ? d.header.recordings[r] : std::string()}});
  }
  Json sets = Json::array();
  for (std::size_t i : StudyReportRanking(d)) {
    const StudyReportSet& s = d.sets[i];
    Json per = Json::array();
    for (const StudyReportCell& c : s.cells) per.push_back(StudyReportNumberJson(c.value));
    sets.push_back({{"set", s.index},
                    {"settings", StudyReportSettingsJson(s.settings)},
                    {"assignments", StudyReportAssignments(s.settings)},
                    {"finished", s.finished},
                    {"failed", s.failed},
                    {"pending", s.pending},
                    {"complete", s.complete},
                    {"mean", StudyReportNumberJson(s.mean)},
                    {"per_recording", per},
                    {"vs_default", StudyReportPairedJson(s.paired)},
                    {"better_than_default", s.better}});
  }
  Json best = nullptr;
  if (d.best >= 0) {
    const StudyReportSet& b = d.sets[static_cast<std::size_t>(d.best)];
    Json commands = Json::array();
    if (b.request) {
      for (std::size_t r = 0; r < d.header.recordings.size() && r < kMaxCommandRecordings; ++r) {
        TrialRequest req = *b.request;
        req.recording = d.header.recordings[r];
        req.em_log = r < d.header.em_logs.size() ? d.header.em_logs[r] : std::string();
        for (const std::string& c : StudyReportCommands(b.settings, req)) commands.push_back(c);
      }
    }
    best = {{"set", b.index},
            {"settings", StudyReportSettingsJson(b.settings)},
            {"assignments", StudyReportAssignments(b.settings)},
            {"mean", StudyReportNumberJson(b.mean)},
            {"default_mean",
             d.default_pos >= 0
                 ? StudyReportNumberJson(d.sets[static_cast<std::size_t>(d.default_pos)].mean)
                 : Json(nullptr)},
            {"vs_default", StudyReportPairedJson(b.paired)},
            {"better_than_default", b.better},
            {"commands", commands}};
  }
  Json per_recording = Json::array();
  for (std::size_t r = 0; r < d.names.size(); ++r) {
    double def = kNaN, bst = kNaN, own = kNaN;
    int own_set = -1;
    if (d.default_pos >= 0) def = d.sets[static_cast<std::size_t>(d.default_pos)].cells[r].value;
    if (d.best >= 0) bst = d.sets[static_cast<std::size_t>(d.best)].cells[r].value;
    for (const StudyReportSet& s : d.sets) {
      const double v = s.cells[r].value;
      if (std::isfinite(v) && (own_set < 0 || StudyReportBetter(v, own, minimize)))
        own = v, own_set = s.index;
    }
    const bool loser =
        std::isfinite(def) && std::isfinite(bst) && StudyReportBetter(def, bst, minimize);
    per_recording.push_back({{"recording", r},
                             {"name", d.names[r]},
                             {"default", StudyReportNumberJson(def)},
                             {"best", StudyReportNumberJson(bst)},
                             {"own_best_set", own_set >= 0 ? Json(own_set) : Json(nullptr)},
                             {"own_best", StudyReportNumberJson(own)},
                             {"best_worse_than_default", loser}});
  }
  Json failures = Json::array();
  for (const StudyReportFailure& f : d.failures)
    failures.push_back(
        {{"id", f.id}, {"set", f.set}, {"recording", f.recording}, {"reason", f.reason}});
  Json spec = Json::parse(d.header.spec_json, nullptr, false);
  if (spec.is_discarded()) spec = d.header.spec_json;
  const Json j = {{"study", d.study.string()},
                  {"objective", d.header.objective},
                  {"unit", d.unit},
                  {"minimize", minimize},
                  {"search", d.header.search},
                  {"parameters", d.header.parameters},
                  {"recordings", recordings},
                  {"statistics",
                   {{"bootstrap_samples", d.options.bootstrap_samples},
                    {"confidence", d.options.confidence},
                    {"seed", d.options.seed},
                    {"significance", kSignificance},
                    {"min_recordings", kMinPairedRecordings}}},
                  {"trials",
                   {{"total", d.trials},
                    {"finished", d.finished},
                    {"failed", d.failed},
                    {"pending", d.pending}}},
                  {"best", best},
                  {"verdict", StudyReportVerdict(d)},
                  {"sets", sets},
                  {"per_recording", per_recording},
                  {"failures", failures},
                  {"problems", d.problems},
                  {"spec", spec}};
  return j;
}

// ---- HTML ----

std::string StudyReportEsc(std::string_view s) { return svg::EscapeHtml(s); }

std::string StudyReportObjectiveTitle(const StudyReportData& d) {
  return d.header.objective + (d.unit.empty() || d.unit == "1" ? "" : " (" + d.unit + ")");
}

std::string StudyReportCi(const PairedComparison& p, int decimals) {
  if (!p.meaningful) return "n &lt; " + std::to_string(kMinPairedRecordings);
  return "[" + html::Fix(p.ci_low, decimals) + ", " + html::Fix(p.ci_high, decimals) + "]";
}

std::string StudyReportP(const PairedComparison& p) {
  if (!p.meaningful) return "&ndash;";
  return html::Sig(p.p_value, 3) + (p.exact ? "" : " (MC)");
}

// Adds one mark per point: a zero-length round-capped segment (x to x + dx), NaN between.
void StudyReportAddMarks(std::vector<svg::Line>& lines, const std::vector<double>& x,
                         const std::vector<double>& y, double dx, const std::string& label,
                         const std::string& color, double width, double opacity) {
  for (std::size_t start = 0; start < x.size(); start += kMarksPerLine) {
    svg::Line l;
    l.label = start == 0 ? label : "";
    l.color = color;
    l.width = width;
    l.opacity = opacity;
    for (std::size_t i = start; i < std::min(x.size(), start + kMarksPerLine); ++i) {
      l.x.insert(l.x.end(), {x[i], x[i] + dx, kNaN});
      l.y.insert(l.y.end(), {y[i], y[i], kNaN});
    }
    lines.push_back(std::move(l));
  }
}

std::string StudyReportParameterPlot(const StudyReportData& d, const std::string& name) {
  std::vector<double> set_x(d.sets.size());
  double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin;
  for (std::size_t i = 0; i < d.sets.size(); ++i) {
    set_x[i] = StudyReportValue(d.sets[i].settings, name);
    if (std::isfinite(set_x[i])) xmin = std::min(xmin, set_x[i]), xmax = std::max(xmax, set_x[i]);
  }
  if (!std::isfinite(xmin)) return "";
  const double dx = std::max(xmax - xmin, std::abs(xmax) * 1e-3 + 1e-9) * 1e-3;
  std::string unit;
  if (const live::ParameterInfo* p = live::FindParameter(name)) unit = p->unit;
  svg::LinePlot plot;
  plot.title = d.header.objective + " against " + name;
  plot.x_title = name + (unit.empty() || unit == "1" ? "" : " (" + unit + ")");
  plot.y_title = StudyReportObjectiveTitle(d);
  plot.width = 570;
  plot.height = 340;
  const bool per_recording = d.names.size() <= kPaletteSize;
  std::vector<std::vector<double>> tx(per_recording ? d.names.size() : 1);
  std::vector<std::vector<double>> ty(tx.size());
  for (std::size_t i = 0; i < d.sets.size(); ++i) {
    if (!std::isfinite(set_x[i])) continue;
    for (std::size_t r = 0; r < d.sets[i].cells.size(); ++r) {
      const double v = d.sets[i].cells[r].value;
      if (!std::isfinite(v)) continue;
      tx[per_recording ? r : 0].push_back(set_x[i]);
      ty[per_recording ? r : 0].push_back(v);
    }
  }
  // Drawn bottom to top: rings for the default and the best set, the trials, the line
  // joining the mean over the sets at each value of this parameter (the other parameters
  // averaged out), each set's mean.
  const auto ring = [&](int pos, const char* label, const char* color) {
    if (pos < 0) return;
    const auto i = static_cast<std::size_t>(pos);
    if (std::isfinite(set_x[i]) && std::isfinite(d.sets[i].mean))
      StudyReportAddMarks(plot.lines, {set_x[i]}, {d.sets[i].mean}, dx, label, color, 14.0, 0.45);
  };
  ring(d.default_pos, "default", "#2ca02c");
  if (d.best != d.default_pos) ring(d.best, "best set", "#d62728");
  for (std::size_t k = 0; k < tx.size(); ++k) {
    StudyReportAddMarks(plot.lines, tx[k], ty[k], dx, per_recording ? d.names[k] : "trials",
                        per_recording ? kPalette[k] : "#7f7f7f", 6.0, 0.7);
  }
  std::vector<double> mx, my;
  std::map<double, std::pair<double, int>> by_x;
  for (std::size_t i = 0; i < d.sets.size(); ++i) {
    if (!std::isfinite(set_x[i]) || !std::isfinite(d.sets[i].mean)) continue;
    mx.push_back(set_x[i]);
    my.push_back(d.sets[i].mean);
    auto& acc = by_x[set_x[i]];
    acc.first += d.sets[i].mean;
    acc.second += 1;
  }
  svg::Line joined;
  joined.label = "mean over sets at each value";
  joined.color = "#222222";
  joined.width = 1.5;
  for (const auto& [x, acc] : by_x) {
    joined.x.push_back(x);
    joined.y.push_back(acc.first / acc.second);
  }
  if (joined.x.size() >= 2) plot.lines.push_back(std::move(joined));
  StudyReportAddMarks(plot.lines, mx, my, dx, "set mean", "#222222", 3.5, 1.0);
  return svg::RenderLinePlot(plot);
}

std::string StudyReportSettingsHtml(const StudyReportData& d, const StudyReportSet& s) {
  if (s.index == 0 && s.settings.empty()) return "<i>default</i>";
  // The tuned parameters first, as the SPEC names them; anything else after.
  std::string out;
  for (const std::string& name : d.header.parameters) {
    const double v = StudyReportValue(s.settings, name);
    if (!out.empty()) out += " ";
    out += "<code>" + StudyReportEsc(live::FormatAssignment({name, v})) + "</code>";
  }
  if (out.empty()) out = "<code>" + StudyReportEsc(StudyReportAssignments(s.settings)) + "</code>";
  return out;
}

std::string StudyReportHtmlPage(const StudyReportData& d) {
  const bool minimize = d.header.minimize;
  const int dec = 3;
  const std::string unit_html = StudyReportEsc(d.unit == "1" ? std::string() : d.unit);
  const StudyReportSet* best = d.best >= 0 ? &d.sets[static_cast<std::size_t>(d.best)] : nullptr;
  const StudyReportSet* def =
      d.default_pos >= 0 ? &d.sets[static_cast<std::size_t>(d.default_pos)] : nullptr;

  const std::vector<std::pair<std::string, std::string>> facts = {
      {"Study", "<code>" + StudyReportEsc(d.study.string()) + "</code>"},
      {"Objective", "<code>" + StudyReportEsc(d.header.objective) + "</code> (" +
                        (minimize ? "lower is better" : "higher is better") + ")"},
      {"Search",
       (d.header.search.empty() ? std::string("&ndash;") : StudyReportEsc(d.header.search)) + ", " +
           std::to_string(d.sets.size()) + " parameter sets"},
      {"Recordings", std::to_string(d.names.size())},
      {"Trials", std::to_string(d.finished) + " finished, " + std::to_string(d.failed) +
                     " failed, " + std::to_string(d.pending) + " not run"},
      {"Best set", best ? "set " + std::to_string(best->index) + ": <b>" +
                              html::Fix(best->mean, dec) + " " + unit_html + "</b>"
                        : std::string("none complete")},
      {"Default (set 0)",
       def ? html::Fix(def->mean, dec) + " " + unit_html : std::string("no trial")},
      {"Generated", StudyReportEsc(html::NowUtc())},
  };
  std::string page = html::PageStart("Tuning study: " + StudyReportEsc(d.study.string()));
  page += html::TopHeader("Tuning study",
                          "echoservo &middot; parameter sets replayed over recordings and "
                          "compared with the default settings",
                          facts);
  page +=
      "<nav class=\"toc\"><a href=\"#summary\">Summary</a><a href=\"#ranking\">Ranking</a>"
      "<a href=\"#parameters\">Against each parameter</a><a href=\"#recordings\">Per "
      "recording</a><a href=\"#failures\">Failed trials</a><a href=\"#replay\">Replay</a>"
      "<a href=\"#spec\">SPEC</a></nav>\n";

  // Summary and the statistics explained.
  const bool ok = best != nullptr && (best->better || best->index == 0);
  page += "<section id=\"summary\"><h2>Summary</h2>";
  page += std::string("<div class=\"verdict ") + (ok ? "ok" : "miss") + "\" id=\"verdict\"><b>" +
          (best == nullptr    ? "No best set."
           : best->index == 0 ? "The default is best."
           : best->better     ? "Better than the default."
                              : "Not shown to be better.") +
          "</b>" + StudyReportEsc(StudyReportVerdict(d)) + "</div>";
  if (best != nullptr) {
    page += "<p>Best set <b>" + std::to_string(best->index) +
            "</b>: " + StudyReportSettingsHtml(d, *best) + ", mean " + html::Fix(best->mean, dec) +
            " " + unit_html;
    if (def != nullptr && best->index != 0) {
      page += "; difference from the default " + html::Fix(best->paired.mean_difference, dec) +
              " " + unit_html + " over " + std::to_string(best->paired.n) + " recordings, " +
              html::Fix(100.0 * d.options.confidence, 0) + "% interval " +
              StudyReportCi(best->paired, dec) + ", p " + StudyReportP(best->paired);
    }
    page += ".</p>";
  }
  page +=
      "<p class=\"note\">How these figures are made. Every set is compared with the default "
      "settings (set 0) <b>on the same recordings</b> (paired): d<sub>r</sub> = objective(set, "
      "r) &minus; objective(default, r) on each recording r where both trials finished. The "
      "<b>difference</b> is the mean of d<sub>r</sub>. Its <b>" +
      html::Fix(100.0 * d.options.confidence, 0) +
      "% confidence interval</b> is a percentile bootstrap over recordings: the d<sub>r</sub> "
      "are resampled with replacement " +
      std::to_string(d.options.bootstrap_samples) + " times (seed " +
      std::to_string(d.options.seed) +
      "), and the interval spans the middle share of the resampled means. The <b>p-value</b> "
      "is a two-sided sign-flip permutation test of &ldquo;the set makes no "
      "difference&rdquo;: under it each d<sub>r</sub> is as likely positive as negative, so p "
      "is the share of the 2<sup>n</sup> sign patterns whose |&Sigma;&plusmn;d<sub>r</sub>| "
      "reaches the observed |&Sigma;d<sub>r</sub>| (every pattern for n &le; " +
      std::to_string(kMaxExactSignFlip) +
      "; a seeded Monte Carlo sample, marked MC, above). With n recordings the smallest "
      "possible p is 2/2<sup>n</sup>, so fewer than 6 recordings can never reach p &lt; " +
      html::Fix(kSignificance, 2) + "; with fewer than " + std::to_string(kMinPairedRecordings) +
      " no interval or test is computed. A set is called <b>better than the default</b> only "
      "when its interval excludes 0 on the better side <b>and</b> p &lt; " +
      html::Fix(kSignificance, 2) +
      ". The <b>best set</b> has the best mean objective among the sets that finished on "
      "every recording. Many sets compared at once make some look better by chance: treat a "
      "p just under the threshold with care, and confirm on recordings the study did not "
      "use.</p>";
  page += "</section>\n";

  // Ranking.
  page += "<section id=\"ranking\"><h2>Ranking</h2><p class=\"note\">Sets by mean objective (" +
          std::string(minimize ? "lowest" : "highest") +
          " first); sets with a trial missing or failed after those complete. Difference = set "
          "&minus; default, on the recordings both finished.</p><div class=\"scroll\"><table>";
  page += html::Row(
      {"rank", "set", "settings", "mean", "finished", "failed", "difference",
       html::Fix(100.0 * d.options.confidence, 0) + "% interval", "p", "better than default"},
      "", true, 3);
  std::size_t rank = 0;
  for (std::size_t i : StudyReportRanking(d)) {
    const StudyReportSet& s = d.sets[i];
    if (++rank > kMaxRankedRows) break;
    std::string better = s.index == 0           ? std::string("baseline")
                         : !s.paired.meaningful ? std::string("not meaningful (n &lt; ") +
                                                      std::to_string(kMinPairedRecordings) + ")"
                                                : html::Tag(s.better);
    page += html::Row(
        {std::to_string(rank), std::to_string(s.index), StudyReportSettingsHtml(d, s),
         html::Fix(s.mean, dec), std::to_string(s.finished) + "/" + std::to_string(s.cells.size()),
         std::to_string(s.failed),
         s.index == 0 ? "&ndash;" : html::Fix(s.paired.mean_difference, dec),
         s.index == 0 ? "&ndash;" : StudyReportCi(s.paired, dec),
         s.index == 0 ? "&ndash;" : StudyReportP(s.paired), better},
        static_cast<int>(i) == d.best ? "final" : "", false, 3);
  }
  page += "</table></div>";
  if (d.sets.size() > kMaxRankedRows)
    page += "<p class=\"note\">" + std::to_string(d.sets.size() - kMaxRankedRows) +
            " more sets in the JSON (<code>echoservo tune report STUDY --json</code>).</p>";
  page += "</section>\n";

  // Against each parameter.
  page +=
      "<section id=\"parameters\"><h2>Objective against each parameter</h2><p "
      "class=\"note\">One small mark per finished trial (coloured by recording), a black "
      "mark per set's mean, the line joining the mean over the sets at each value of the "
      "parameter (the other parameters averaged out); the best set in red, the default in "
      "green (rings). Failed and missing trials have no mark.</p><div class=\"grid2\">";
  std::size_t plots = 0;
  for (const std::string& name : d.header.parameters) {
    const std::string svg_text = StudyReportParameterPlot(d, name);
    if (svg_text.empty()) continue;
    page += "<div>" + svg_text + "</div>";
    ++plots;
  }
  page += "</div>";
  if (plots == 0) page += "<p>No tuned parameter with a value to plot.</p>";
  page += "</section>\n";

  // Per recording.
  page +=
      "<section id=\"recordings\"><h2>Per recording</h2><p class=\"note\">The default "
      "against the best set on each recording, and the recording's own best set. "
      "Highlighted: recordings where the best set does worse than the default (losers).</p>"
      "<div class=\"scroll\"><table>";
  page += html::Row({"recording", "default", "best set", "best &minus; default", "own best set",
                     "own best", "best set worse"},
                    "", true, 1);
  std::size_t losers = 0;
  for (std::size_t r = 0; r < d.names.size(); ++r) {
    const double dv = def ? def->cells[r].value : kNaN;
    const double bv = best ? best->cells[r].value : kNaN;
    double own = kNaN;
    int own_set = -1;
    for (const StudyReportSet& s : d.sets) {
      const double v = s.cells[r].value;
      if (std::isfinite(v) && (own_set < 0 || StudyReportBetter(v, own, minimize)))
        own = v, own_set = s.index;
    }
    const bool loser =
        std::isfinite(dv) && std::isfinite(bv) && StudyReportBetter(dv, bv, minimize);
    losers += loser ? 1 : 0;
    page += html::Row(
        {StudyReportEsc(d.names[r]), html::Fix(dv, dec), html::Fix(bv, dec),
         html::Fix(bv - dv, dec), own_set >= 0 ? std::to_string(own_set) : std::string("&ndash;"),
         html::Fix(own, dec), loser ? html::Tag(true, "worse") : std::string("")},
        loser ? "sig" : "", false, 1);
  }
  page += "</table></div><p>" + std::to_string(losers) + " of " + std::to_string(d.names.size()) +
          " recordings do worse with the best set than with the default.</p></section>\n";

  // Failures and problems.
  page += "<section id=\"failures\"><h2>Failed trials</h2>";
  if (d.failures.empty()) {
    page += "<p>None.</p>";
  } else {
    page += "<div class=\"scroll\"><table>" +
            html::Row({"trial", "set", "recording", "reason"}, "", true, 4);
    for (const StudyReportFailure& f : d.failures) {
      page +=
          html::Row({"<code>" + StudyReportEsc(f.id) + "</code>", std::to_string(f.set),
                     StudyReportEsc(d.names[static_cast<std::size_t>(f.recording)]),
                     "<span style=\"white-space:normal\">" + StudyReportEsc(f.reason) + "</span>"},
                    "", false, 4);
    }
    page += "</table></div>";
  }
  if (d.pending > 0)
    page += "<p class=\"note\">" + std::to_string(d.pending) +
            " trials have not run yet (rerun the study: finished trials are skipped).</p>";
  if (!d.problems.empty()) {
    page += "<h3>Problems with the STUDY files</h3><ul>";
    for (const std::string& p : d.problems) page += "<li>" + StudyReportEsc(p) + "</li>";
    page += "</ul>";
  }
  page += "</section>\n";

  // Replay commands.
  page += "<section id=\"replay\"><h2>Replay the best setting</h2>";
  if (best == nullptr || !best->request) {
    page += "<p>No best set.</p>";
  } else {
    page +=
        "<p class=\"note\">One trial scored as the study scored it, and the tracker "
        "replaying the recording with the same settings (follower and servo settings act "
        "in the re-simulated loop of <code>tune trial</code> only).</p>";
    for (std::size_t r = 0; r < d.header.recordings.size() && r < kMaxCommandRecordings; ++r) {
      TrialRequest req = *best->request;
      req.recording = d.header.recordings[r];
      req.em_log = r < d.header.em_logs.size() ? d.header.em_logs[r] : std::string();
      page += "<h3>" + StudyReportEsc(d.names[r]) + "</h3>";
      for (const std::string& c : StudyReportCommands(best->settings, req))
        page += "<p><code>" + StudyReportEsc(c) + "</code></p>";
    }
  }
  page += "</section>\n";

  // The SPEC.
  Json spec = Json::parse(d.header.spec_json, nullptr, false);
  page +=
      "<section id=\"spec\"><h2>SPEC</h2><p class=\"note\">" +
      (d.header.spec_path.empty() ? std::string("")
                                  : "<code>" + StudyReportEsc(d.header.spec_path) + "</code>, ") +
      "as the study read it.</p><pre>" +
      StudyReportEsc(spec.is_discarded() ? d.header.spec_json : spec.dump(2)) +
      "</pre></section>\n";
  page +=
      "<footer>Generated by <code>echoservo tune report</code>. Self-contained page: no external "
      "resources.</footer></main></body></html>\n";
  return page;
}

}  // namespace

std::string StudyReportJson(const fs::path& study, const StudyReportOptions& o) {
  return StudyReportToJson(StudyReportAnalyze(study, o)).dump(2);
}

std::string StudyReportHtml(const fs::path& study, const StudyReportOptions& o) {
  return StudyReportHtmlPage(StudyReportAnalyze(study, o));
}

}  // namespace echoservo::tune
