#include "live/pipeline_parameters.h"

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "estimation/heartbeat_ekf.h"
#include "estimation/heartbeat_significance.h"
#include "estimation/predictor_competition.h"
#include "live/demo_run.h"

namespace echoservo::live {
namespace {

struct ParamEntry {
  ParameterInfo info;
  std::function<double(const PipelineSettings&)> get;
  std::function<void(PipelineSettings&, double)> set;
};

// `field` is a generic accessor (auto& s) -> auto&: the same lambda reads a const settings
// object and writes a mutable one.
template <class Field>
ParamEntry MakeParam(std::string name, std::string unit, ParameterKind kind, double min, double max,
                     std::string description, Field field) {
  ParamEntry e;
  e.info.name = std::move(name);
  e.info.unit = std::move(unit);
  e.info.kind = kind;
  e.info.min = min;
  e.info.max = max;
  e.info.stage = e.info.name.substr(0, e.info.name.find('.'));
  e.info.description = std::move(description);
  e.get = [field](const PipelineSettings& s) { return static_cast<double>(field(s)); };
  e.set = [field](PipelineSettings& s, double v) {
    using T = std::remove_reference_t<decltype(field(s))>;
    if constexpr (std::is_same_v<T, bool>) {
      field(s) = v != 0.0;
    } else if constexpr (std::is_integral_v<T>) {
      field(s) = static_cast<T>(std::llround(v));
    } else {
      field(s) = v;
    }
  };
  return e;
}

template <class Field>
ParamEntry RealParam(std::string name, std::string unit, double min, double max,
                     std::string description, Field field) {
  return MakeParam(std::move(name), std::move(unit), ParameterKind::kReal, min, max,
                   std::move(description), field);
}

template <class Field>
ParamEntry IntParam(std::string name, double min, double max, std::string description,
                    Field field) {
  return MakeParam(std::move(name), "1", ParameterKind::kInteger, min, max, std::move(description),
                   field);
}

template <class Field>
ParamEntry BoolParam(std::string name, std::string description, Field field) {
  return MakeParam(std::move(name), "1", ParameterKind::kBool, 0.0, 1.0, std::move(description),
                   field);
}

std::vector<ParamEntry> BuildParamTable() {
  std::vector<ParamEntry> t;
  // --- detector: tracking::RadonDetectorOptions (tracking/radon_detector.h) --------------
  t.push_back(IntParam(
      "detector.coarse_directions", 100, 20000,
      "directions of the coarse Radon search's hemisphere (angular step ~sqrt(2pi/N): 0.18 rad "
      "at 200, 0.018 rad at 20000); the detector's main cost",
      [](auto& s) -> auto& { return s.tracker.detector.coarse_directions; }));
  t.push_back(RealParam(
      "detector.dynamic_range_db", "dB", 10, 120,
      "the scanner's display dynamic range (0-255 spans it): edges and the tube "
      "check work in echo amplitude; clinical 3D scanners use 30-80 dB",
      [](auto& s) -> auto& { return s.tracker.detector.edge.dynamic_range_db; }));
  t.push_back(RealParam(
      "detector.first_echo_mm", "mm", 0, 20,
      "axis fit: look-back along the beam for the first-echo rule (a brighter echo "
      "this close nearer the probe makes a sample a reverberation); 0: off",
      [](auto& s) -> auto& { return s.tracker.detector.fit.first_echo_mm; }));
  t.push_back(RealParam(
      "detector.fit_radius_mm", "mm", 0.5, 10,
      "axis fit: echoes within this distance of the Radon line join the fit (the "
      "catheter's radius plus the point-spread function)",
      [](auto& s) -> auto& { return s.tracker.detector.fit.fit_radius_mm; }));
  t.push_back(RealParam(
      "detector.min_confidence", "1", 0, 1,
      "detections below this confidence are not found (tracking falls back to a "
      "full search)",
      [](auto& s) -> auto& { return s.tracker.detector.min_confidence; }));
  t.push_back(RealParam(
      "detector.sheath_diameter_mm", "mm", 0, 10,
      "the sheath's outer diameter: a beam echoes at the near wall, so the axis "
      "lies a radius behind the echoes; 0: the echoes are the axis; <= 10 mm (30 Fr)",
      [](auto& s) -> auto& { return s.tracker.detector.fit.sheath_diameter_mm; }));
  t.push_back(RealParam(
      "detector.tracking_cone_rad", "rad", 0.02, 1.0,
      "tracking searches this half-angle around the previous axis (the catheter's "
      "turn between volumes); 1 rad is nearly a full search",
      [](auto& s) -> auto& { return s.tracker.detector.tracking_cone_rad; }));
  t.push_back(RealParam(
      "detector.tracking_window_mm", "mm", 0.5, 30,
      "tracking searches offsets this far around the previous axis (the "
      "catheter's sideways motion between volumes)",
      [](auto& s) -> auto& { return s.tracker.detector.tracking_window_mm; }));
  t.push_back(RealParam(
      "detector.wire_diameter_mm", "mm", 0, 10,
      "the guidewire's outer diameter (its near-wall offset beyond the sheath), at "
      "most the sheath's",
      [](auto& s) -> auto& { return s.tracker.detector.fit.wire_diameter_mm; }));
  // --- target: the profile along the axis, tracking::EdgeOptions (tracking/axis_profile.h)
  t.push_back(RealParam(
      "target.close_gap_mm", "mm", 1.5, 20,
      "gaps below this come from the surface beside the tip (the tip's and the "
      "tissue's echoes merge on the axis: about the axial resolution, >= 1.5 mm)",
      [](auto& s) -> auto& { return s.tracker.detector.edge.close_gap_mm; }));
  t.push_back(RealParam(
      "target.contact_gap_mm", "mm", 0, 2,
      "at or below this gap the tip touches the tissue (contact, gap 0); less than "
      "target.close_gap_mm",
      [](auto& s) -> auto& { return s.tracker.detector.edge.contact_gap_mm; }));
  t.push_back(RealParam(
      "target.edge_fraction", "1", 0.05, 0.95,
      "tip and target edges at this fraction between background and echo level, in "
      "echo amplitude (0.5: the half-amplitude point of a symmetric blur)",
      [](auto& s) -> auto& { return s.tracker.detector.edge.edge_fraction; }));
  t.push_back(RealParam(
      "target.lateral_radius_mm", "mm", 0.5, 20,
      "the target search's rays beside the tip run at this radius from the axis "
      "(beyond the catheter's own echo)",
      [](auto& s) -> auto& { return s.tracker.detector.edge.lateral_radius_mm; }));
  t.push_back(RealParam(
      "target.tip_first_echo_mm", "mm", 0, 20,
      "the tip's edge uses first echoes only: a brighter sample this close nearer "
      "the probe marks a reverberation tail; 0: off",
      [](auto& s) -> auto& { return s.tracker.detector.edge.tip_first_echo_mm; }));
  // --- predictor: the heartbeat EKF and the predictor competition (live/tracker_node.h) ----
  t.push_back(RealParam(
      "predictor.coefficient_q_mm", "mm/sqrt(s)", 1e-4, 1,
      "EKF random walk of the Fourier coefficients (the beat's shape changing)",
      [](auto& s) -> auto& { return s.tracker.ekf.coefficient_q_mm; }));
  t.push_back(RealParam(
      "predictor.gate_sigma", "1", 1, 20,
      "EKF outlier gate: measurements further than this many predicted sigma are "
      "rejected",
      [](auto& s) -> auto& { return s.tracker.ekf.gate_sigma; }));
  t.push_back(IntParam(
      "predictor.harmonics", 0, 12,
      "EKF harmonics of the heartbeat's shape; 0: chosen at initialisation "
      "(cross-validated) up to predictor.max_harmonics",
      [](auto& s) -> auto& { return s.tracker.ekf.harmonics; }));
  t.push_back(RealParam(
      "predictor.init_window_s", "s", 1.7, 30,
      "EKF initial (and re-acquisition) window; >= one beat at its lowest rate "
      "(0.6 Hz: 1.67 s)",
      [](auto& s) -> auto& { return s.tracker.ekf.init_window_s; }));
  t.push_back(RealParam(
      "predictor.latency_s", "s", 0, 1,
      "the horizon the predictor competition scores its competitors at: the "
      "imaging delay plus publication",
      [](auto& s) -> auto& { return s.tracker.prediction_latency_s; }));
  t.push_back(RealParam(
      "scanner.stamp_delay_s", "s", 0, 0.5,
      "how late the scanner stamps its volumes after acquiring them (stamped at sending: "
      "PLUS's LocalTimeOffsetSec of a video device); the tracker subtracts it",
      [](auto& s) -> auto& { return s.tracker.stamp_delay_s; }));
  t.push_back(IntParam(
      "predictor.max_harmonics", 1, 12,
      "the automatic harmonic choice's upper end (used when predictor.harmonics "
      "is 0)",
      [](auto& s) -> auto& { return s.tracker.ekf.max_harmonics; }));
  t.push_back(RealParam(
      "predictor.noise_mm", "mm", 0, 5,
      "EKF measurement sigma; 0: the initial fit's residual (floored at 0.02 mm)",
      [](auto& s) -> auto& { return s.tracker.ekf.noise_mm; }));
  t.push_back(RealParam(
      "predictor.offset_q_mm", "mm/sqrt(s)", 1e-3, 5,
      "EKF random walk of the motion's offset (drift, slow respiration)",
      [](auto& s) -> auto& { return s.tracker.ekf.offset_q_mm; }));
  t.push_back(RealParam(
      "predictor.phase_q_rad", "rad/sqrt(s)", 1e-4, 1, "EKF random walk of the cardiac phase",
      [](auto& s) -> auto& { return s.tracker.ekf.phase_q_rad; }));
  t.push_back(RealParam(
      "predictor.rate_q_rad_s", "rad/s/sqrt(s)", 1e-3, 10,
      "EKF random walk of the heart rate (heart-rate variability)",
      [](auto& s) -> auto& { return s.tracker.ekf.rate_q_rad_s; }));
  {
    // An enum (live::TargetPredictor), not a bool field: its own accessors.
    ParamEntry e;
    e.info = {"predictor.zero_order_hold",
              "1",
              ParameterKind::kBool,
              0.0,
              1.0,
              0.0,
              "predictor",
              "1: publish the newest measurement as a constant (the baseline: no prediction "
              "through the delay) instead of the predictor competition's motion"};
    e.get = [](const PipelineSettings& s) {
      return s.tracker.predictor == TargetPredictor::kZeroOrderHold ? 1.0 : 0.0;
    };
    e.set = [](PipelineSettings& s, double v) {
      s.tracker.predictor =
          v != 0.0 ? TargetPredictor::kZeroOrderHold : TargetPredictor::kHeartbeatEkf;
    };
    t.push_back(std::move(e));
  }
  // --- follower: control::FollowerConfig (control/target_follower.h) ---------------------
  t.push_back(BoolParam(
      "follower.estimate_scale",
      "1: fit the image/catheter scale online (a sound speed other than the "
      "scanner's makes image mm differ from catheter mm); 0: scale 1",
      [](auto& s) -> auto& { return s.follower.estimate_scale; }));
  t.push_back(RealParam(
      "follower.min_confidence", "1", 0, 1,
      "the servo ignores estimates below this confidence (counted)",
      [](auto& s) -> auto& { return s.follower.min_confidence; }));
  t.push_back(RealParam(
      "follower.offset_gain", "1", 1e-3, 1,
      "low-pass gain per volume of the image-to-catheter offset (1: the newest "
      "volume's alone)",
      [](auto& s) -> auto& { return s.follower.offset_gain; }));
  t.push_back(RealParam(
      "follower.stale_after_s", "s", 0.02, 5,
      "no fresh estimate for this long: hold (then retract); >= one volume "
      "interval at 60 vol/s",
      [](auto& s) -> auto& { return s.follower.stale_after_s; }));
  t.push_back(RealParam(
      "follower.standoff_mm", "mm", 0, 30,
      "the tip is held this far short of the target along the axis (0: contact)",
      [](auto& s) -> auto& { return s.follower.standoff_mm; }));
  // --- servo: control::ServoConfig gains (control/servo_loop.h, control/pid.h) ------------
  t.push_back(RealParam(
      "servo.coulomb_ff_n", "N", 0, 5,
      "friction feed-forward: Coulomb term (calibration measures it; the "
      "simulated catheter's nominal friction)",
      [](auto& s) -> auto& { return s.servo.feedforward.coulomb_n; }));
  t.push_back(RealParam(
      "servo.kd_n_per_mm_per_s", "N/(mm/s)", 0, 1,
      "PID derivative gain of the base position loop (on the measurement, "
      "low-passed)",
      [](auto& s) -> auto& { return s.servo.pid.kd_n_per_mm_per_s; }));
  t.push_back(RealParam(
      "servo.ki_n_per_mm_s", "N/(mm*s)", 0, 5000, "PID integral gain of the base position loop",
      [](auto& s) -> auto& { return s.servo.pid.ki_n_per_mm_s; }));
  t.push_back(RealParam(
      "servo.kp_n_per_mm", "N/mm", 0, 100,
      "PID proportional gain of the base position loop (100 N/mm saturates the "
      "26.7 N actuator at 0.27 mm of error)",
      [](auto& s) -> auto& { return s.servo.pid.kp_n_per_mm; }));
  t.push_back(RealParam(
      "servo.viscous_ff_n_per_mm_s", "N/(mm/s)", 0, 0.1, "friction feed-forward: viscous term",
      [](auto& s) -> auto& { return s.servo.feedforward.viscous_n_per_mm_s; }));

  std::sort(t.begin(), t.end(),
            [](const ParamEntry& a, const ParamEntry& b) { return a.info.name < b.info.name; });
  const PipelineSettings defaults = DefaultSettings();
  for (ParamEntry& e : t) {
    e.info.default_value = e.get(defaults);
    assert(e.info.min <= e.info.default_value && e.info.default_value <= e.info.max);
  }
  return t;
}

const std::vector<ParamEntry>& ParamTable() {
  static const std::vector<ParamEntry> table = BuildParamTable();
  return table;
}

const ParamEntry* FindParamEntry(std::string_view name) {
  const std::vector<ParamEntry>& t = ParamTable();
  const auto it =
      std::lower_bound(t.begin(), t.end(), name,
                       [](const ParamEntry& e, std::string_view n) { return e.info.name < n; });
  return it != t.end() && it->info.name == name ? &*it : nullptr;
}

std::size_t ParamEditDistance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

// How far `query` is from the known `name`: the edit distance to the dotted name, or to its
// part after the stage (a name given without its stage), or 1 when `name` starts with it.
std::size_t ParamCloseness(std::string_view query, std::string_view name) {
  std::size_t d = ParamEditDistance(query, name);
  const std::size_t dot = name.find('.');
  if (dot != std::string_view::npos)
    d = std::min(d, ParamEditDistance(query, name.substr(dot + 1)) + 1);
  if (!query.empty() && name.substr(0, query.size()) == query) d = std::min<std::size_t>(d, 1);
  return d;
}

// The shortest "%g" text that reads back to v, in positional notation where %g allows it
// (2000, not 2e+03).
std::string ParamNumber(double v) {
  char buf[40];
  const bool exponent_ok = !(std::fabs(v) >= 1e-4 && std::fabs(v) < 1e16);
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof buf, "%.*g", precision, v);
    const bool positional = std::string_view(buf).find('e') == std::string_view::npos;
    if (std::strtod(buf, nullptr) == v && (positional || exponent_ok)) return buf;
  }
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string ParamNamed(std::string_view name, double value) {
  return std::string(name) + " = " + ParamNumber(value);
}

// The stage's assigned parameters, for a message ("none: the defaults" when none).
std::string ParamsAssignedIn(const std::vector<Assignment>& assignments, const std::string& stage) {
  std::string out;
  for (const Assignment& a : assignments) {
    if (a.first.compare(0, stage.size() + 1, stage + ".") != 0) continue;
    out += (out.empty() ? "" : ", ") + FormatAssignment(a);
  }
  return out.empty() ? "no " + stage + ".* parameter set" : "set: " + out;
}

}  // namespace

PipelineSettings DefaultSettings() {
  // `demo` with its defaults: the tracker node's options (8 harmonics, a 2 s window: also
  // `track`'s), the demo's follower and the simulated catheter's servo.
  static const PipelineSettings defaults = DemoSettings(DemoOptions{});
  return defaults;
}

const std::vector<ParameterInfo>& Parameters() {
  static const std::vector<ParameterInfo> infos = [] {
    std::vector<ParameterInfo> v;
    for (const ParamEntry& e : ParamTable()) v.push_back(e.info);
    return v;
  }();
  return infos;
}

const ParameterInfo* FindParameter(std::string_view name) {
  const ParamEntry* e = FindParamEntry(name);
  return e ? &Parameters()[static_cast<std::size_t>(e - ParamTable().data())] : nullptr;
}

std::vector<std::string> ClosestParameters(std::string_view name, std::size_t count) {
  std::vector<std::pair<std::size_t, std::string>> scored;
  for (const ParamEntry& e : ParamTable())
    scored.emplace_back(ParamCloseness(name, e.info.name), e.info.name);
  std::sort(scored.begin(), scored.end());
  std::vector<std::string> out;
  for (std::size_t i = 0; i < scored.size() && i < count; ++i) out.push_back(scored[i].second);
  return out;
}

const ParameterInfo& RequireParameter(std::string_view name) {
  if (const ParameterInfo* p = FindParameter(name)) return *p;
  std::string closest;
  for (const std::string& c : ClosestParameters(name, 3))
    closest += (closest.empty() ? "" : ", ") + c;
  throw std::invalid_argument("unknown parameter '" + std::string(name) + "' (closest: " + closest +
                              "; see `echoservo tune params`)");
}

void CheckValue(const ParameterInfo& p, double value) {
  const std::string head = "parameter '" + p.name + "' = " + ParamNumber(value);
  if (!std::isfinite(value)) throw std::invalid_argument(head + ": must be a finite number");
  if (p.kind == ParameterKind::kInteger && value != std::round(value))
    throw std::invalid_argument(head + ": must be an integer");
  if (p.kind == ParameterKind::kBool && value != 0.0 && value != 1.0)
    throw std::invalid_argument(head + ": must be 0 or 1 (a boolean)");
  if (value < p.min || value > p.max)
    throw std::invalid_argument(head + ": outside its bounds [" + ParamNumber(p.min) + ", " +
                                ParamNumber(p.max) + "]" + (p.unit == "1" ? "" : " " + p.unit));
}

double Get(const PipelineSettings& s, std::string_view name) {
  RequireParameter(name);
  return FindParamEntry(name)->get(s);
}

void Set(PipelineSettings& s, std::string_view name, double value) {
  const ParameterInfo& p = RequireParameter(name);
  CheckValue(p, value);
  FindParamEntry(name)->set(s, value);
}

Assignment ParseAssignment(std::string_view text, std::string_view where) {
  const std::string w = where.empty() ? std::string() : std::string(where) + " ";
  const std::size_t eq = text.find('=');
  if (eq == std::string_view::npos || eq == 0 || eq + 1 == text.size())
    throw std::invalid_argument(w + "'" + std::string(text) +
                                "': expected name=value (e.g. detector.sheath_diameter_mm=2.5; "
                                "see `echoservo tune params`)");
  const std::string name(text.substr(0, eq));
  const std::string value_text(text.substr(eq + 1));
  const ParameterInfo* p = FindParameter(name);
  try {
    if (!p) RequireParameter(name);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(w + std::string(text) + ": " + e.what());
  }
  double value = 0.0;
  if (p->kind == ParameterKind::kBool && (value_text == "true" || value_text == "false")) {
    value = value_text == "true" ? 1.0 : 0.0;
  } else {
    char* end = nullptr;
    errno = 0;
    value = std::strtod(value_text.c_str(), &end);
    const bool spaces = value_text.find_first_of(" \t\n") != std::string::npos;
    if (end != value_text.c_str() + value_text.size() || spaces || errno == ERANGE)
      throw std::invalid_argument(w + std::string(text) + ": '" + value_text + "' is not a number" +
                                  (p->kind == ParameterKind::kBool ? " (a boolean: 0 or 1)" : ""));
  }
  try {
    CheckValue(*p, value);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(w + std::string(text) + ": " + e.what());
  }
  return {name, value};
}

std::vector<Assignment> ParseAssignments(const std::vector<std::string>& texts,
                                         std::string_view where) {
  std::vector<Assignment> out;
  out.reserve(texts.size());
  for (const std::string& t : texts) out.push_back(ParseAssignment(t, where));
  return out;
}

void Apply(const std::vector<Assignment>& assignments, PipelineSettings& s) {
  PipelineSettings next = s;  // s is left as it was when an assignment or the result is bad
  for (const Assignment& a : assignments) Set(next, a.first, a.second);

  // The combinations the registry's bounds cannot express, named by parameter.
  auto require = [&](bool ok, std::string_view a, std::string_view relation, std::string_view b,
                     const std::string& why) {
    if (!ok)
      throw std::invalid_argument(ParamNamed(a, Get(next, a)) + " must be " +
                                  std::string(relation) + " " + ParamNamed(b, Get(next, b)) + " (" +
                                  why + ")");
  };
  const auto& fit = next.tracker.detector.fit;
  const auto& edge = next.tracker.detector.edge;
  require(fit.wire_diameter_mm <= fit.sheath_diameter_mm, "detector.wire_diameter_mm",
          "<=", "detector.sheath_diameter_mm", "the guidewire runs inside the sheath");
  require(edge.contact_gap_mm < edge.close_gap_mm, "target.contact_gap_mm", "<",
          "target.close_gap_mm", "contact is the closest of the close gaps");

  // Then each stage's own validation, for whatever the registry does not know of.
  auto stage = [&](const std::string& name, const std::function<void()>& validate) {
    try {
      validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("the " + name + " settings are inconsistent (" +
                                  ParamsAssignedIn(assignments, name) + "): " + e.what());
    }
  };
  stage("detector", [&] { next.tracker.detector.Validate(); });
  stage("predictor", [&] {
    estimation::PredictorCompetition competition(next.tracker.CompetitionOptions());
    estimation::HeartbeatSignificance significance(next.tracker.significance);
  });
  stage("follower", [&] { next.follower.Validate(); });
  stage("servo", [&] { next.servo.Validate(); });
  s = std::move(next);
}

std::string FormatAssignment(const Assignment& a) { return a.first + "=" + ParamNumber(a.second); }

std::vector<Assignment> AllValues(const PipelineSettings& s) {
  std::vector<Assignment> out;
  for (const ParamEntry& e : ParamTable()) out.emplace_back(e.info.name, e.get(s));
  return out;
}

std::string SettingsJson(const PipelineSettings& s) {
  std::string out = "{";
  for (const ParamEntry& e : ParamTable()) {
    if (out.size() > 1) out += ", ";
    out += "\"" + e.info.name + "\": " + ParamNumber(e.get(s));
  }
  return out + "}";
}

std::vector<Assignment> RequireStages(const std::vector<Assignment>& assignments,
                                      std::string_view command,
                                      const std::vector<std::string>& stages) {
  for (const Assignment& a : assignments) {
    const std::string& stage = RequireParameter(a.first).stage;
    if (std::find(stages.begin(), stages.end(), stage) != stages.end()) continue;
    std::string runs;
    for (const std::string& st : stages) runs += (runs.empty() ? "" : ", ") + st + ".*";
    throw std::invalid_argument("--set " + FormatAssignment(a) +
                                ": the parameter does not apply to `" + std::string(command) +
                                "` (its stage '" + stage + "' does not run there; it runs " + runs +
                                ")");
  }
  return assignments;
}

void ApplyFor(std::string_view command, const std::vector<std::string>& stages,
              const std::vector<Assignment>& assignments, PipelineSettings& s) {
  RequireStages(assignments, command, stages);
  try {
    Apply(assignments, s);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string(command) + " --set: " + e.what());
  }
}

}  // namespace echoservo::live
