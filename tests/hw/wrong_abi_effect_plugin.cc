// An effect plugin built for another ABI (hw/effect_plugin.h): the loader must refuse it
// before calling its registration function.
#include <cstdlib>

#include "hw/effect_plugin.h"

extern "C" int echoservo_effect_plugin_abi() { return echoservo::hw::kEffectPluginAbi + 1; }

extern "C" void echoservo_register_effects(echoservo::hw::EffectRegistry&) { std::abort(); }
