// The tracker path's tunable parameters, by dotted name: what `echoservo tune params`
// lists, what `--set name=value` (track, demo, detect, tune trial) and a tuning SPEC
// (tune/study_spec.h) accept. In live (not tune) because `demo` applies them too.
//
// Each parameter has a unit (mm, s, rad, dB, N and their combinations such as N/mm or
// mm/sqrt(s), or 1 for a ratio/count), closed bounds [min, max] that Set enforces, its
// default (the live pipeline's), and the stage it acts on (the name's first part):
// "scanner" (what the tracker assumes of the scanner's clock: TrackerNodeOptions::
// stamp_delay_s), "detector" (tracking::RadonDetectorOptions, with the scanner's dynamic range that
// its edges and tube check share), "target" (the target profile: tracking::EdgeOptions),
// "predictor" (the heartbeat EKF and the predictor competition: live::TrackerNodeOptions),
// "follower" (control::FollowerConfig: standoff, staleness, offset fit) and "servo"
// (control::ServoConfig gains: used where a replay re-simulates the loop on the simulated plant,
// tune/trial.h). Integer and boolean parameters are real numbers on the wire: an integer must be
// integral, a boolean 0 or 1. Errors: std::invalid_argument naming the parameter (unknown: with the
// closest known names; outside its bounds: with the bounds and unit; malformed "name=value").
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "control/servo_loop.h"
#include "control/target_follower.h"
#include "formats/parameter_spec.h"
#include "live/tracker_node.h"

namespace echoservo::live {

using ParameterKind = formats::ParameterKind;

struct ParameterInfo {
  std::string name;  // dotted, e.g. "detector.sheath_diameter_mm"
  std::string unit;  // "mm", "s", "rad", "Hz", "dB", "1"
  ParameterKind kind = ParameterKind::kReal;
  double min = 0.0, max = 0.0;  // inclusive bounds
  double default_value = 0.0;   // the live pipeline's
  std::string stage;            // "scanner", "detector", "target", "predictor", "follower", "servo"
  std::string description;      // one line
};

// Everything a parameter can change: the tracker node's options (detector, target profile,
// predictor), the servo's follower and its loop (gains; the re-simulated loop only).
// The live pipeline's follower, declared here once: the module's defaults (control/
// target_follower.h) with the water tank's standoff of 8 mm and the image/catheter scale
// fitted online (image mm = 1540/1482 catheter mm in water at the scanner's 1540 m/s).
control::FollowerConfig LiveFollowerConfig();

struct PipelineSettings {
  live::TrackerNodeOptions tracker;  // its defaults: the live tracker's (DefaultEkfOptions)
  control::FollowerConfig follower = LiveFollowerConfig();
  control::ServoConfig servo;  // DefaultSettings: the simulated catheter's calibrated servo
};

// The live pipeline's settings (what `track`, `servo`, `demo` and a replay run without --set):
// PipelineSettings{} with the simulated catheter's calibrated servo (live/sim_catheter.h, the
// seed's catheter, seed 1). The registry's defaults (`tune params`).
PipelineSettings DefaultSettings();

// For tests of the one-declaration rule: sets `name` without the registry's bounds check, so
// that the modules' own validation (ValidateSettings) can be seen to enforce the same bounds.
void SetUnchecked(PipelineSettings& s, std::string_view name, double value);
// Every module's validation of `s` and the combinations the bounds cannot express; throws
// std::invalid_argument naming the parameter (Apply runs it after the assignments).
void ValidateSettings(const PipelineSettings& s);

// Every parameter, sorted by name.
const std::vector<ParameterInfo>& Parameters();
// nullptr when unknown.
const ParameterInfo* FindParameter(std::string_view name);
// The parameter; throws std::invalid_argument "unknown parameter 'x' (closest: a, b, c; see
// `echoservo tune params`)".
const ParameterInfo& RequireParameter(std::string_view name);

// Throws std::invalid_argument naming the parameter when `value` is not finite, outside the
// bounds, not integral (kInteger) or not 0/1 (kBool).
void CheckValue(const ParameterInfo& p, double value);

double Get(const PipelineSettings& s, std::string_view name);
// Checks (CheckValue) and sets; throws std::invalid_argument.
void Set(PipelineSettings& s, std::string_view name, double value);

using Assignment = std::pair<std::string, double>;
// "name=value" → the assignment, checked; `where` prefixes the error ("--set").
Assignment ParseAssignment(std::string_view text, std::string_view where);
std::vector<Assignment> ParseAssignments(const std::vector<std::string>& texts,
                                         std::string_view where);
// Applies in order, then validates the combination (the detector's, the EKF's, the
// follower's and the servo's own Validate); throws std::invalid_argument.
void Apply(const std::vector<Assignment>& assignments, PipelineSettings& s);

// The stages each runtime runs, for the one --set filter (RequireStages): the tracker
// runtime's (`track`), the servo runtime's (`servo`), both (`demo`, `tune trial`).
inline const std::vector<std::string> kTrackerStages = {"scanner", "detector", "target",
                                                        "predictor"};
inline const std::vector<std::string> kServoStages = {"follower", "servo"};
inline const std::vector<std::string> kAllStages = {"scanner",   "detector", "target",
                                                    "predictor", "follower", "servo"};

// The one --set filter of every command: each assignment's stage must be among `stages`,
// else std::invalid_argument "--set NAME=VALUE: the parameter does not apply to `command`
// (its stage 'S' does not run there; it runs scanner.*, detector.*, ...)". Returns them.
std::vector<Assignment> RequireStages(const std::vector<Assignment>& assignments,
                                      std::string_view command,
                                      const std::vector<std::string>& stages);
// RequireStages, then Apply; errors name `command` and --set.
void ApplyFor(std::string_view command, const std::vector<std::string>& stages,
              const std::vector<Assignment>& assignments, PipelineSettings& s);

// "name=value" with the shortest text that reads back to the same double ("%.17g" trimmed).
std::string FormatAssignment(const Assignment& a);

// The `count` known names closest to `name` (edit distance, also to the part after the
// stage; a known name that starts with `name` counts as close), closest first.
std::vector<std::string> ClosestParameters(std::string_view name, std::size_t count);
// Every parameter's value in `s`, sorted by name (what a RUN's run.json records).
std::vector<Assignment> AllValues(const PipelineSettings& s);
// The same as a JSON object {"name": value, ...} (numbers as FormatAssignment writes them).
std::string SettingsJson(const PipelineSettings& s);

}  // namespace echoservo::live
