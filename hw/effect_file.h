// Effects written as a file instead of C++: a JSON document of parameters and expressions
// (hw/expression.h) over named inputs, so that a user adds a catheter effect without
// rebuilding.
//
// A file ("format": "echoservo.effect/1") names the effect, describes it, lists its
// parameters (name, unit, default, bounds, doc) and gives one expression per hook it
// implements, e.g. {"friction_n": "a_n*exp(-((base_mm-x0_mm)/w_mm)^2)"}. Each hook
// (CatheterHooks) maps to one hw::Effect hook and sees the parameters plus its inputs; the
// constant `pi` is always defined. Units follow the names (mm, s, N, rad; the `_n`, `_mm`,
// `_s` suffixes); a parameter's unit is a required string ("1" for dimensionless). The
// parser is generic over the hook list, so another lab can reuse the format with its own
// hooks. Format, hooks and examples: docs/effect_files.md.
// Tabulated terms ("tables"): a piecewise-linear (bilinear for a pair) function of one or
// two hook inputs through knots, e.g. a shape `lab diagnose` learnt from data. In a hook's
// expression the table's name is its value at the sample's inputs; its knot values are
// fitted parameters `<table>_<k>` (after the explicit ones in Effect::parameters()), and
// the effect evaluates the table with the current parameter values. A table refuses inputs
// outside its knots (EffectTableRangeError) instead of extrapolating.
// Errors: EffectFileError naming the file, the JSON key (`parameters[1].upper`,
// `expressions.friction_n`, `tables[0].knots[1]`) or the line and column, and why.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "hw/effect.h"
#include "hw/effect_registry.h"

namespace echoservo::hw {

inline constexpr std::string_view kEffectFileFormat = "echoservo.effect/1";

// One hook an effect file may implement: its key, the inputs its expression may use
// besides the parameters, the unit of its value, and the inputs' typical values (same
// order) at which every expression must be finite with the parameters at their defaults.
struct HookDefinition {
  std::string name;
  std::vector<std::string> inputs;
  std::string unit;
  std::string doc;
  std::vector<double> typical_inputs;
};

// The catheter model's hooks (hw/effect.h): friction_n, friction_scale, force_n,
// drive_offset_mm, backlash_width_mm, traversal_tau_s, sensor_delay_s, sensor_scale,
// sensor_offset_mm. Geometry inputs: bend_rad, bend_deg, gap_mm, tip_load_n.
const std::vector<HookDefinition>& CatheterHooks();

// A tabulated term: values at the knots of one input or of a pair, interpolated linearly
// (bilinearly) between them. Its knot values are the effect's parameters `<name>_<k>`
// (k row-major), with `unit`, bounds [lower, upper] and `values[k]` as default.
struct EffectTableSpec {
  std::string name;                        // [a-z][a-z0-9_]*, a variable of the expressions
  std::vector<std::string> inputs;         // 1 or 2 hook input names
  std::vector<std::vector<double>> knots;  // one strictly increasing array (>= 2) per input
  std::vector<double> values;              // row-major, first input slowest: v[i0*n1 + i1]
  std::string unit;                        // of the values; "1" for dimensionless
  double lower = 0.0;                      // bounds of every knot value (and of the fit)
  double upper = 0.0;
  std::string doc;
  bool operator==(const EffectTableSpec&) const = default;
};

struct EffectFileSpec {
  std::string name;
  std::string description;
  std::string signature;
  std::vector<ParameterSpec> parameters;  // the explicit ones (tables add theirs after)
  std::vector<std::pair<std::string, std::string>> expressions;  // hook, text (file order)
  std::string path;                     // where it was read from or written to; "" in memory
  std::vector<EffectTableSpec> tables;  // tabulated terms, file order
};

// Field by field, parameters included (ParameterSpec has no operator==).
bool operator==(const EffectFileSpec& a, const EffectFileSpec& b);

class EffectFileError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// A table evaluated at an input outside its knots (tabulated terms do not extrapolate).
class EffectTableRangeError : public EffectFileError {
 public:
  using EffectFileError::EffectFileError;
};

// The name of knot value `k` (row-major) of table `table`: "<table>_<k>".
std::string TableParameterName(const std::string& table, std::size_t k);
// Every parameter of the effect a spec describes, as Effect::parameters() lists them: the
// explicit ones, then each table's knot values (default values[k], the table's unit and
// bounds).
std::vector<ParameterSpec> EffectFileParameters(const EffectFileSpec& spec);

// Reads and validates an effect file. Throws EffectFileError (the file cannot be read,
// invalid JSON, missing or unknown keys, wrong format, bad name, bad parameter, bad table,
// bad or non-finite expression, a table used by a hook without its inputs).
EffectFileSpec ReadEffectFile(const std::filesystem::path& path,
                              const std::vector<HookDefinition>& hooks = CatheterHooks());
// The same for text in memory; `origin` names it in errors.
EffectFileSpec ParseEffectJson(const std::string& text, const std::string& origin,
                               const std::vector<HookDefinition>& hooks = CatheterHooks());
// The JSON text of a spec (what WriteEffectFile writes).
std::string EffectJson(const EffectFileSpec& spec);
// Writes atomically (temporary file + rename); ReadEffectFile gives `spec` back (but for
// `path`). Throws std::runtime_error naming the file when it cannot be written.
void WriteEffectFile(const std::filesystem::path& path, const EffectFileSpec& spec);

// An Effect evaluating a validated spec with the catheter hooks (one parser per instance:
// never share an instance between threads). Its stage follows its first hook. Throws
// EffectFileError for a bad table or a table used by a hook without its inputs; its hooks
// throw EffectTableRangeError for a table input outside the knots.
std::unique_ptr<Effect> MakeExpressionEffect(const EffectFileSpec& spec);
// Registers the spec under spec.name with spec.path as its source. Throws
// std::invalid_argument when the name is taken.
void RegisterEffectSpec(EffectRegistry& registry, const EffectFileSpec& spec);

}  // namespace echoservo::hw
