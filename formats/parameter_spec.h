// The declaration of one tunable parameter: its dotted name ("detector.sheath_diameter_mm"),
// unit, kind, closed bounds, the owning option's default and a one-line description. Each
// module declares its tunable fields' specs once, next to the option struct (e.g.
// tracking::params in tracking/radon_detector.h); the struct's default, the module's Validate
// (Check) and the pipeline's registry (live/pipeline_parameters.h: `tune params`, `--set`, a
// SPEC's axes, run.json's "settings") all read that one declaration, as ROS 2's
// generate_parameter_library does. Here because the registry's file forms (SPEC, run.json)
// are file contracts and every module may depend on this ground-level library.
// Units: mm, s, rad, dB, N and their products; "1" for a ratio, a count or a boolean.
#pragma once

#include <string>
#include <string_view>

namespace echoservo::formats {

enum class ParameterKind { kReal, kInteger, kBool };

struct ParameterSpec {
  std::string_view name;  // "<stage>.<field>_<unit>": the stage is the part before the dot
  std::string_view unit;
  ParameterKind kind = ParameterKind::kReal;
  double min = 0.0, max = 0.0;  // inclusive
  double default_value = 0.0;   // the owning option struct's default
  std::string_view description;

  constexpr std::string_view stage() const { return name.substr(0, name.find('.')); }
  // Throws std::invalid_argument "<owner>: parameter '<name>' = <value>: <why>" when `value`
  // is not finite, outside [min, max] (naming the bounds and unit), not integral (kInteger)
  // or not 0/1 (kBool).
  void Check(double value, std::string_view owner) const;
};

// The shortest "%g" text that reads back to `v` (positional where %g allows it).
std::string FormatParameterValue(double v);

}  // namespace echoservo::formats
