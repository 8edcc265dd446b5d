#include "apps/commands/effect_catalog_flags.h"

#include <CLI/CLI.hpp>
#include <algorithm>

#include "hw/effect_plugin.h"
#include "hw/effect_registry.h"

namespace echoservo::apps {

void AddCatalogFlags(CLI::App* app, CatalogFlags& flags) {
  app->add_option("--plugin", flags.plugins,
                  "Load catheter effects from a compiled plugin FILE.so (repeatable; "
                  "docs/effect_files.md#plugins)");
}

hw::EffectRegistry& BuildCatalog(const CatalogFlags& flags) {
  static hw::EffectRegistry catalog = hw::EffectRegistry::WithBuiltinEffects();
  static std::vector<std::string> loaded;
  for (const std::string& plugin : flags.plugins) {
    if (std::find(loaded.begin(), loaded.end(), plugin) != loaded.end()) continue;
    hw::LoadEffectPlugin(plugin, catalog);
    loaded.push_back(plugin);
  }
  hw::SetDefaultEffectRegistry(&catalog);
  return catalog;
}

}  // namespace echoservo::apps
