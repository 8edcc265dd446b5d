// Compiled effect plugins: a shared library (built against this tree's headers with the
// same compiler and flags) that registers its own hw::Effect classes in a registry at run
// time, for effects an expression file cannot say (state, tables, iterative physics).
//
// A plugin exports two C functions:
//   extern "C" int echoservo_effect_plugin_abi() { return echoservo::hw::kEffectPluginAbi; }
//   extern "C" void echoservo_register_effects(echoservo::hw::EffectRegistry& registry);
// The loader refuses a plugin whose ABI number differs from kEffectPluginAbi. The plugin
// calls into the executable's hw code (EffectRegistry::Register): the program that loads
// plugins exports its symbols (CMake ENABLE_EXPORTS) and the plugin does not link the hw
// library itself. Units and hooks: hw/effect.h; example: hw/plugins/example_effect_plugin.cc;
// docs/effect_files.md#plugins.
#pragma once

#include <filesystem>
#include <stdexcept>

#include "hw/effect_registry.h"

namespace echoservo::hw {

// Bump when hw::Effect's or hw::EffectRegistry's layout or virtual functions change, or
// the two entry points' signatures do: older plugins are then refused instead of crashing.
inline constexpr int kEffectPluginAbi = 1;

inline constexpr const char* kEffectPluginAbiSymbol = "echoservo_effect_plugin_abi";
inline constexpr const char* kEffectPluginRegisterSymbol = "echoservo_register_effects";

class EffectPluginError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// Loads `so` (dlopen; it stays loaded for the life of the process) and lets it register
// its effects in `registry`. Throws EffectPluginError naming the file and why: dlopen's
// error, a missing entry point, or an ABI number other than kEffectPluginAbi (both
// given); std::invalid_argument from the registry for a name it already holds.
void LoadEffectPlugin(const std::filesystem::path& so, EffectRegistry& registry);

}  // namespace echoservo::hw
