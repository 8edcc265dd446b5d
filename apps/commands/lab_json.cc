#include "apps/commands/lab_json.h"

#include <nlohmann/json.hpp>

namespace echoservo::apps {

nlohmann::json WhereJson(const std::vector<lab::WhereEntry>& where) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& e : where) {
    out.push_back({{"channel", e.channel},
                   {"variable", e.variable},
                   {"explained_fraction", e.explained_fraction},
                   {"gain_noise_var", e.gain}});
  }
  return out;
}

}  // namespace echoservo::apps
