// The catalog of catheter effects and the model SPEC grammar.
//
// A registry maps effect names (exactly the catalog names: `coulomb_friction`,
// `viscous_friction`, `backlash`, ...) to factories. A model SPEC is a `+`-separated
// list of names; the alias `seed` expands to the seed's model
// (`coulomb_friction+viscous_friction+backlash`). Effects are always evaluated in the
// catalog's pipeline order, whatever order the SPEC names them in.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "hw/effect.h"

namespace echoservo::hw {

class EffectRegistry {
 public:
  using Factory = std::function<std::unique_ptr<Effect>()>;

  // Throws std::invalid_argument for an empty or duplicate name, or a factory whose
  // effect reports another name.
  void Register(const std::string& name, Factory factory);
  // Throws std::invalid_argument naming the unknown effect and listing the known ones.
  std::unique_ptr<Effect> Create(std::string_view name) const;
  bool Contains(std::string_view name) const;
  // Names in registration (pipeline) order.
  std::vector<std::string> Names() const;

  // A registry holding every built-in catalog effect.
  static EffectRegistry WithBuiltinEffects();

 private:
  std::vector<std::pair<std::string, Factory>> entries_;
};

// The effects of the seed's model.
const std::vector<std::string>& SeedEffects();

// Parses "seed+capstan_friction+sensor_delay" into catalog names (aliases expanded,
// duplicates rejected, names checked against `registry`), ordered as the registry
// orders them. Throws std::invalid_argument with the offending token.
std::vector<std::string> ParseModelSpec(std::string_view spec, const EffectRegistry& registry);
std::string FormatModelSpec(const std::vector<std::string>& effects);

}  // namespace echoservo::hw
