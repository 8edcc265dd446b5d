#include "hw/effect_registry.h"

#include <algorithm>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "hw/effect_file.h"
#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {

void EffectRegistry::Register(const std::string& name, Factory factory, std::string source) {
  if (name.empty()) throw std::invalid_argument("effect registry: empty effect name");
  if (Contains(name))
    throw std::invalid_argument("effect registry: '" + name + "' registered twice");
  if (!factory) throw std::invalid_argument("effect registry: '" + name + "' has no factory");
  const auto probe = factory();
  if (!probe || probe->name() != name) {
    throw std::invalid_argument("effect registry: factory for '" + name +
                                "' makes an effect with another name");
  }
  entries_.push_back({name, std::move(factory), std::move(source)});
}

std::string EffectRegistry::Source(std::string_view name) const {
  for (const auto& e : entries_) {
    if (e.name == name) return e.source;
  }
  return "";
}

bool EffectRegistry::Contains(std::string_view name) const {
  return std::any_of(entries_.begin(), entries_.end(),
                     [&](const auto& e) { return e.name == name; });
}

std::vector<std::string> EffectRegistry::Names() const {
  std::vector<std::string> names;
  for (const auto& e : entries_) names.push_back(e.name);
  return names;
}

std::unique_ptr<Effect> EffectRegistry::Create(std::string_view name) const {
  for (const auto& e : entries_) {
    if (e.name == name) return e.factory();
  }
  std::string known;
  for (const auto& e : entries_) known += (known.empty() ? "" : ", ") + e.name;
  throw std::invalid_argument("unknown effect '" + std::string(name) + "' (known: seed, " + known +
                              ")");
}

EffectRegistry EffectRegistry::WithBuiltinEffects() {
  EffectRegistry r;
  // Pipeline order: friction, its scaling, compliance, deadzone width, tip dynamics, sensor.
  r.Register("coulomb_friction", MakeCoulombFriction);
  r.Register("viscous_friction", MakeViscousFriction);
  r.Register("stribeck_friction", MakeStribeckFriction);
  r.Register("capstan_friction", MakeCapstanFriction);
  r.Register("guidewire_compliance", MakeGuidewireCompliance);
  r.Register("backlash", MakeBacklash);
  r.Register("friction_backlash", MakeFrictionBacklash);
  r.Register("deadzone_traversal", MakeDeadzoneTraversal);
  r.Register("sensor_delay", MakeSensorDelay);
  r.Register("tip_sensor_scale", MakeTipSensorScale);
  return r;
}

const std::vector<std::string>& SeedEffects() {
  static const std::vector<std::string> seed = {"coulomb_friction", "viscous_friction", "backlash"};
  return seed;
}

std::vector<std::string> ParseModelSpec(std::string_view spec, const EffectRegistry& registry) {
  if (spec.empty()) throw std::invalid_argument("model spec is empty (try 'seed')");
  std::vector<std::string> names;
  std::size_t start = 0;
  while (start <= spec.size()) {
    const std::size_t end = std::min(spec.find('+', start), spec.size());
    const std::string token(spec.substr(start, end - start));
    if (token.empty()) {
      throw std::invalid_argument("model spec '" + std::string(spec) +
                                  "': empty effect name at offset " + std::to_string(start));
    }
    const std::vector<std::string> expanded =
        token == "seed" ? SeedEffects() : std::vector<std::string>{token};
    for (const std::string& name : expanded) {
      if (!registry.Contains(name)) registry.Create(name);  // throws with the known names
      if (std::find(names.begin(), names.end(), name) != names.end()) {
        throw std::invalid_argument("model spec '" + std::string(spec) + "': effect '" + name +
                                    "' named twice");
      }
      names.push_back(name);
    }
    start = end + 1;
  }
  const std::vector<std::string> order = registry.Names();
  std::sort(names.begin(), names.end(), [&](const std::string& a, const std::string& b) {
    return std::find(order.begin(), order.end(), a) < std::find(order.begin(), order.end(), b);
  });
  return names;
}

std::string FormatModelSpec(const std::vector<std::string>& effects) {
  std::vector<std::string> rest = effects;
  std::string out;
  const auto& seed = SeedEffects();
  if (std::all_of(seed.begin(), seed.end(), [&](const std::string& s) {
        return std::find(rest.begin(), rest.end(), s) != rest.end();
      })) {
    out = "seed";
    std::erase_if(rest, [&](const std::string& s) {
      return std::find(seed.begin(), seed.end(), s) != seed.end();
    });
  }
  for (const std::string& s : rest) out += (out.empty() ? "" : "+") + s;
  return out;
}

namespace {

// Whether two spellings of a path name the same file (the same canonical path, or the
// same text when neither can be resolved).
bool SameFile(const std::string& a, const std::string& b) {
  std::error_code ea, eb;
  const auto ca = std::filesystem::weakly_canonical(a, ea);
  const auto cb = std::filesystem::weakly_canonical(b, eb);
  if (ea || eb) return a == b;
  return ca == cb;
}

}  // namespace

std::vector<std::string> ResolveModelSpec(std::string_view spec, EffectRegistry& registry) {
  std::string names;  // the SPEC with every @path replaced by the file's effect name
  std::size_t start = 0;
  while (start <= spec.size()) {
    const std::size_t end = std::min(spec.find('+', start), spec.size());
    std::string token(spec.substr(start, end - start));
    if (token.size() > 1 && token[0] == '@') {
      const std::string path = token.substr(1);
      const EffectFileSpec file = ReadEffectFile(path);
      if (registry.Contains(file.name)) {
        const std::string source = registry.Source(file.name);
        if (source.empty()) {
          throw std::invalid_argument("model spec '" + std::string(spec) + "': effect file " +
                                      path + " defines '" + file.name +
                                      "', the name of a built-in or plugin effect; rename it");
        }
        if (!SameFile(source, path)) {
          throw std::invalid_argument("model spec '" + std::string(spec) + "': effect '" +
                                      file.name + "' is defined by two files, " + source + " and " +
                                      path + "; rename one");
        }
      } else {
        RegisterEffectSpec(registry, file);
      }
      token = file.name;
    } else if (token == "@") {
      throw std::invalid_argument("model spec '" + std::string(spec) +
                                  "': '@' without an effect file path at offset " +
                                  std::to_string(start));
    }
    names += (start == 0 ? "" : "+") + token;
    start = end + 1;
  }
  return ParseModelSpec(names, registry);
}

std::string FormatModelSpec(const std::vector<std::string>& effects,
                            const EffectRegistry& registry) {
  std::vector<std::string> named;
  std::vector<std::string> files;
  for (const std::string& e : effects) {
    const std::string source = registry.Source(e);
    if (source.empty()) {
      named.push_back(e);
    } else {
      files.push_back("@" + source);
    }
  }
  std::string out = named.empty() ? "" : FormatModelSpec(named);
  for (const std::string& f : files) out += (out.empty() ? "" : "+") + f;
  return out;
}

namespace {
const EffectRegistry* g_default_registry = nullptr;
}  // namespace

const EffectRegistry& DefaultEffectRegistry() {
  static const EffectRegistry builtin = EffectRegistry::WithBuiltinEffects();
  return g_default_registry != nullptr ? *g_default_registry : builtin;
}

void SetDefaultEffectRegistry(const EffectRegistry* registry) { g_default_registry = registry; }

}  // namespace echoservo::hw
