// JSON pieces shared by `lab compare|diagnose` on catheter datasets and on motion traces.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <vector>

#include "lab/residual_structure.h"

namespace echoservo::apps {

// `where`: [{"channel", "variable", "explained_fraction", "gain_noise_var"}, …], ranked.
nlohmann::json WhereJson(const std::vector<lab::WhereEntry>& where);

}  // namespace echoservo::apps
