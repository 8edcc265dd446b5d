// The effect catalog of a command: the built-in effects plus the compiled plugins the
// user names with --plugin FILE.so (repeatable; hw/effect_plugin.h). Effect files join
// the catalog through `@path` tokens in a model SPEC (hw::ResolveModelSpec).
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace echoservo::hw {
class EffectRegistry;
}

namespace echoservo::apps {

struct CatalogFlags {
  std::vector<std::string> plugins;
};

void AddCatalogFlags(CLI::App* app, CatalogFlags& flags);

// The process's catalog: the built-ins plus every plugin in `flags` (each loaded once,
// however often this is called), installed as hw::DefaultEffectRegistry() so that plants
// the experiments build see it too. Lives for the whole process. Throws
// hw::EffectPluginError for a plugin that cannot be loaded.
hw::EffectRegistry& BuildCatalog(const CatalogFlags& flags);

}  // namespace echoservo::apps
