// The catalog of catheter effects and the model SPEC grammar.
//
// A registry maps effect names (exactly the catalog names: `coulomb_friction`,
// `viscous_friction`, `backlash`, ...) to factories. A model SPEC is a `+`-separated
// list of names; the alias `seed` expands to the seed's model
// (`coulomb_friction+viscous_friction+backlash`). Effects are always evaluated in the
// catalog's pipeline order, whatever order the SPEC names them in.
//
// Effects a user adds without rebuilding come after the built-ins, in registration order:
// effect files (hw/effect_file.h) and compiled plugins (hw/effect_plugin.h). In a SPEC
// given to ResolveModelSpec, a token `@path/to/effect.json` reads that effect file and
// registers it under the file's "name" (e.g. `seed+@effects/tight_spot.json`); paths must
// not contain '+'. FormatModelSpec(effects, registry) writes file effects back as `@path`,
// so a printed SPEC can be passed again to --model/--effects. Format: docs/effect_files.md.
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
  // `source`: the effect file it was read from ("" for built-ins and plugins).
  void Register(const std::string& name, Factory factory, std::string source = "");
  // Throws std::invalid_argument naming the unknown effect and listing the known ones.
  std::unique_ptr<Effect> Create(std::string_view name) const;
  bool Contains(std::string_view name) const;
  // Names in registration (pipeline) order.
  std::vector<std::string> Names() const;
  // The effect file `name` was read from; "" for built-ins, plugins and unknown names.
  std::string Source(std::string_view name) const;

  // A registry holding every built-in catalog effect.
  static EffectRegistry WithBuiltinEffects();

 private:
  struct Entry {
    std::string name;
    Factory factory;
    std::string source;
  };
  std::vector<Entry> entries_;
};

// The effects of the seed's model.
const std::vector<std::string>& SeedEffects();

// Parses "seed+capstan_friction+sensor_delay" into catalog names (aliases expanded,
// duplicates rejected, names checked against `registry`), ordered as the registry
// orders them. Throws std::invalid_argument with the offending token.
std::vector<std::string> ParseModelSpec(std::string_view spec, const EffectRegistry& registry);
std::string FormatModelSpec(const std::vector<std::string>& effects);

// ParseModelSpec that also accepts `@path` tokens: each reads an effect file
// (hw/effect_file.h) and registers it in `registry`, unless the same file already
// registered that name. Throws hw::EffectFileError for a bad file and
// std::invalid_argument when the file's name is already taken by another file or by a
// built-in or plugin effect (naming both).
std::vector<std::string> ResolveModelSpec(std::string_view spec, EffectRegistry& registry);
// FormatModelSpec writing the effects read from files as `@path` (their Source).
std::string FormatModelSpec(const std::vector<std::string>& effects,
                            const EffectRegistry& registry);

// The catalog a SimulatedCatheter uses when PlantOptions::registry is null: the built-in
// catalog, or the registry a program installed with SetDefaultEffectRegistry (the CLI
// installs its catalog with the user's plugins and effect files once, before it builds any
// plant, so that the experiments building their own plants see them). Not synchronised:
// install before any thread builds a plant. The registry must outlive its use; null
// restores the built-ins.
const EffectRegistry& DefaultEffectRegistry();
void SetDefaultEffectRegistry(const EffectRegistry* registry);

}  // namespace echoservo::hw
