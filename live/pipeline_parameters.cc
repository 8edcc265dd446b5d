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
#include "live/sim_catheter.h"

namespace echoservo::live {
namespace {

struct ParamEntry {
  ParameterInfo info;
  const formats::ParameterSpec* spec = nullptr;  // the module's declaration
  std::function<double(const PipelineSettings&)> get;
  std::function<void(PipelineSettings&, double)> set;
};

// `field` is a generic accessor (auto& s) -> auto&: the same lambda reads a const settings
// object and writes a mutable one.
// `field` is a generic accessor (auto& s) -> auto&: the same lambda reads a const settings
// object and writes a mutable one. Name, unit, kind, bounds and description: the module's
// declaration (formats/parameter_spec.h); the default: the pipeline's (BuildParamTable).
template <class Field>
ParamEntry Param(const formats::ParameterSpec& spec, Field field) {
  ParamEntry e;
  e.info.name = std::string(spec.name);
  e.info.unit = std::string(spec.unit);
  e.info.kind = spec.kind;
  e.info.min = spec.min;
  e.info.max = spec.max;
  e.info.stage = std::string(spec.stage());
  e.info.description = std::string(spec.description);
  e.spec = &spec;
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

std::vector<ParamEntry> BuildParamTable() {
  namespace tp = tracking::params;
  namespace ep = estimation::params;
  namespace cp = control::params;
  std::vector<ParamEntry> t;
  // --- detector: tracking::RadonDetectorOptions (tracking/radon_detector.h) ---------------
  t.push_back(Param(
      tp::kCoarseDirections,
      [](auto& s) -> auto& { return s.tracker.detector.coarse_directions; }));
  t.push_back(Param(
      tp::kDynamicRangeDb,
      [](auto& s) -> auto& { return s.tracker.detector.edge.dynamic_range_db; }));
  t.push_back(Param(
      tp::kFirstEchoMm, [](auto& s) -> auto& { return s.tracker.detector.fit.first_echo_mm; }));
  t.push_back(Param(
      tp::kFitRadiusMm, [](auto& s) -> auto& { return s.tracker.detector.fit.fit_radius_mm; }));
  t.push_back(Param(
      tp::kMinConfidence, [](auto& s) -> auto& { return s.tracker.detector.min_confidence; }));
  t.push_back(Param(
      tp::kSheathDiameterMm,
      [](auto& s) -> auto& { return s.tracker.detector.fit.sheath_diameter_mm; }));
  t.push_back(Param(
      tp::kTrackingConeRad, [](auto& s) -> auto& { return s.tracker.detector.tracking_cone_rad; }));
  t.push_back(Param(
      tp::kTrackingWindowMm,
      [](auto& s) -> auto& { return s.tracker.detector.tracking_window_mm; }));
  t.push_back(Param(
      tp::kWireDiameterMm,
      [](auto& s) -> auto& { return s.tracker.detector.fit.wire_diameter_mm; }));
  // --- target: the profile along the axis, tracking::EdgeOptions (tracking/axis_profile.h)
  t.push_back(Param(
      tp::kCloseGapMm, [](auto& s) -> auto& { return s.tracker.detector.edge.close_gap_mm; }));
  t.push_back(Param(
      tp::kContactGapMm, [](auto& s) -> auto& { return s.tracker.detector.edge.contact_gap_mm; }));
  t.push_back(Param(
      tp::kEdgeFraction, [](auto& s) -> auto& { return s.tracker.detector.edge.edge_fraction; }));
  t.push_back(Param(
      tp::kLateralRadiusMm,
      [](auto& s) -> auto& { return s.tracker.detector.edge.lateral_radius_mm; }));
  t.push_back(Param(
      tp::kTipFirstEchoMm,
      [](auto& s) -> auto& { return s.tracker.detector.edge.tip_first_echo_mm; }));
  // --- predictor: the heartbeat EKF (estimation/heartbeat_ekf.h) and the tracker node ---------
  t.push_back(Param(
      ep::kCoefficientQMm, [](auto& s) -> auto& { return s.tracker.ekf.coefficient_q_mm; }));
  t.push_back(Param(
      ep::kGateSigma, [](auto& s) -> auto& { return s.tracker.ekf.gate_sigma; }));
  t.push_back(Param(
      ep::kHarmonics, [](auto& s) -> auto& { return s.tracker.ekf.harmonics; }));
  t.push_back(Param(
      ep::kInitWindowS, [](auto& s) -> auto& { return s.tracker.ekf.init_window_s; }));
  t.push_back(Param(
      ep::kMaxHarmonics, [](auto& s) -> auto& { return s.tracker.ekf.max_harmonics; }));
  t.push_back(Param(
      ep::kNoiseMm, [](auto& s) -> auto& { return s.tracker.ekf.noise_mm; }));
  t.push_back(Param(
      ep::kOffsetQMm, [](auto& s) -> auto& { return s.tracker.ekf.offset_q_mm; }));
  t.push_back(Param(
      ep::kPhaseQRad, [](auto& s) -> auto& { return s.tracker.ekf.phase_q_rad; }));
  t.push_back(Param(
      ep::kRateQRadS, [](auto& s) -> auto& { return s.tracker.ekf.rate_q_rad_s; }));
  t.push_back(Param(
      params::kPredictionLatencyS,
      [](auto& s) -> auto& { return s.tracker.prediction_latency_s; }));
  t.push_back(Param(
      params::kStampDelayS, [](auto& s) -> auto& { return s.tracker.stamp_delay_s; }));
  {
    // An enum (live::TargetPredictor), not a bool field: its own accessors.
    ParamEntry e = Param(
        params::kZeroOrderHold, [](auto& s) -> auto& { return s.tracker.follow_static_target; });
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
  t.push_back(Param(
      cp::kEstimateScale, [](auto& s) -> auto& { return s.follower.estimate_scale; }));
  t.push_back(Param(
      cp::kMinConfidence, [](auto& s) -> auto& { return s.follower.min_confidence; }));
  t.push_back(Param(
      cp::kOffsetGain, [](auto& s) -> auto& { return s.follower.offset_gain; }));
  t.push_back(Param(
      cp::kStaleAfterS, [](auto& s) -> auto& { return s.follower.stale_after_s; }));
  t.push_back(Param(
      cp::kStandoffMm, [](auto& s) -> auto& { return s.follower.standoff_mm; }));
  // --- servo: control::ServoConfig gains (control/pid.h, control/friction_feedforward.h) --
  t.push_back(Param(
      cp::kCoulombFfN, [](auto& s) -> auto& { return s.servo.feedforward.coulomb_n; }));
  t.push_back(Param(
      cp::kKdNPerMmPerS, [](auto& s) -> auto& { return s.servo.pid.kd_n_per_mm_per_s; }));
  t.push_back(Param(
      cp::kKiNPerMmS, [](auto& s) -> auto& { return s.servo.pid.ki_n_per_mm_s; }));
  t.push_back(Param(
      cp::kKpNPerMm, [](auto& s) -> auto& { return s.servo.pid.kp_n_per_mm; }));
  t.push_back(Param(
      cp::kViscousFfNPerMmS,
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

std::string ParamNamed(std::string_view name, double value) {
  return std::string(name) + " = " + formats::FormatParameterValue(value);
}

}  // namespace

control::FollowerConfig LiveFollowerConfig() {
  control::FollowerConfig f;
  f.standoff_mm = 8.0;
  f.estimate_scale = true;
  return f;
}

PipelineSettings DefaultSettings() {
  static const PipelineSettings defaults = [] {
    PipelineSettings s;
    s.servo = MakeSimCatheter(DemoOptions{}.sheath_id_mm, DemoOptions{}.guidewire_od_mm,
                              DemoOptions{}.seed)
                  .servo;
    return s;
  }();
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
  RequireParameter(p.name);
  FindParamEntry(p.name)->spec->Check(value, "");
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

void SetUnchecked(PipelineSettings& s, std::string_view name, double value) {
  RequireParameter(name);
  FindParamEntry(name)->set(s, value);
}

void ValidateSettings(const PipelineSettings& next) {
  // The combinations the bounds cannot express, named by parameter.
  auto require = [&](bool ok, std::string_view a, std::string_view relation, std::string_view b,
                     const std::string& why) {
    if (!ok)
      throw std::invalid_argument(ParamNamed(a, Get(next, a)) + " must be " +
                                  std::string(relation) + " " + ParamNamed(b, Get(next, b)) + " (" +
                                  why + ")");
  };
  const auto& fit = next.tracker.detector.fit;
  const auto& edge = next.tracker.detector.edge;
  if (fit.sheath_diameter_mm > 0)
    require(fit.wire_diameter_mm < fit.sheath_diameter_mm, "detector.wire_diameter_mm", "<",
            "detector.sheath_diameter_mm", "the guidewire runs in the sheath's lumen");
  else
    require(fit.wire_diameter_mm == 0, "detector.wire_diameter_mm", "0 with",
            "detector.sheath_diameter_mm", "no near-wall model without a sheath");
  require(fit.sheath_diameter_mm <= 2 * fit.fit_radius_mm, "detector.sheath_diameter_mm", "<= 2 x",
          "detector.fit_radius_mm",
          "the axis fit gathers the wall's echoes within fit_radius_mm of their line; raise it "
          "for a wider sheath");
  require(edge.contact_gap_mm < edge.close_gap_mm, "target.contact_gap_mm", "<",
          "target.close_gap_mm", "contact is the closest of the close gaps");
  // Then each stage's own validation: the bounds the modules declare, and what else they check.
  auto stage = [&](const std::string& name, const std::function<void()>& validate) {
    try {
      validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("the " + name + " settings are inconsistent: " + e.what());
    }
  };
  stage("tracker", [&] {
    next.tracker.Validate();
    estimation::PredictorCompetition competition(next.tracker.CompetitionOptions());
    estimation::HeartbeatSignificance significance(next.tracker.significance);
  });
  stage("follower", [&] { next.follower.Validate(); });
  stage("servo", [&] { next.servo.Validate(); });
}

void Apply(const std::vector<Assignment>& assignments, PipelineSettings& s) {
  PipelineSettings next = s;  // s is left as it was when an assignment or the result is bad
  for (const Assignment& a : assignments) Set(next, a.first, a.second);
  try {
    ValidateSettings(next);
  } catch (const std::invalid_argument& e) {
    std::string assigned;
    for (const Assignment& a : assignments)
      assigned += (assigned.empty() ? "" : ", ") + FormatAssignment(a);
    throw std::invalid_argument(std::string(e.what()) +
                                (assigned.empty() ? "" : " (set: " + assigned + ")"));
  }
  s = std::move(next);
}

std::string FormatAssignment(const Assignment& a) {
  return a.first + "=" + formats::FormatParameterValue(a.second);
}

std::vector<Assignment> AllValues(const PipelineSettings& s) {
  std::vector<Assignment> out;
  for (const ParamEntry& e : ParamTable()) out.emplace_back(e.info.name, e.get(s));
  return out;
}

std::string SettingsJson(const PipelineSettings& s) {
  std::string out = "{";
  for (const ParamEntry& e : ParamTable()) {
    if (out.size() > 1) out += ", ";
    out += "\"" + e.info.name + "\": " + formats::FormatParameterValue(e.get(s));
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
