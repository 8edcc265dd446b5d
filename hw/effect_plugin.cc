#include "hw/effect_plugin.h"

#include <dlfcn.h>

#include <string>

namespace echoservo::hw {

void LoadEffectPlugin(const std::filesystem::path& so, EffectRegistry& registry) {
  const std::string file = so.string();
  // dlopen looks a bare name up in the library path; a path with a '/' is opened as is.
  const std::string open_name = file.find('/') == std::string::npos ? "./" + file : file;
  void* handle = ::dlopen(open_name.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* why = ::dlerror();
    throw EffectPluginError(file + ": cannot load the effect plugin: " +
                            (why != nullptr ? why : "unknown dlopen error"));
  }
  // The handle is never closed: the registry's factories live in the plugin's code.
  using AbiFn = int (*)();
  using RegisterFn = void (*)(EffectRegistry&);
  ::dlerror();
  void* abi_symbol = ::dlsym(handle, kEffectPluginAbiSymbol);
  if (abi_symbol == nullptr) {
    throw EffectPluginError(file + ": not an echoservo effect plugin: it does not export " +
                            kEffectPluginAbiSymbol + "()");
  }
  const int abi = reinterpret_cast<AbiFn>(abi_symbol)();
  if (abi != kEffectPluginAbi) {
    throw EffectPluginError(file + ": effect plugin ABI " + std::to_string(abi) +
                            ", this program expects ABI " + std::to_string(kEffectPluginAbi) +
                            " (rebuild the plugin against this version)");
  }
  void* register_symbol = ::dlsym(handle, kEffectPluginRegisterSymbol);
  if (register_symbol == nullptr) {
    throw EffectPluginError(file + ": the effect plugin does not export " +
                            kEffectPluginRegisterSymbol + "(echoservo::hw::EffectRegistry&)");
  }
  reinterpret_cast<RegisterFn>(register_symbol)(registry);
}

}  // namespace echoservo::hw
