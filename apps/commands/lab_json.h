// JSON pieces shared by `lab compare|diagnose` on catheter datasets and on motion traces.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <ostream>
#include <vector>

#include "lab/learned_term.h"
#include "lab/residual_structure.h"

namespace echoservo::apps {

// `where`: [{"channel", "variable", "explained_fraction", "gain_noise_var"}, …], ranked.
nlohmann::json WhereJson(const std::vector<lab::WhereEntry>& where);

// What the lab learnt beyond its libraries (lab/learned_term.h): each screened shape as a
// table of knots and values, the Pareto front of formulas, what is proposed and why.
nlohmann::json LearningJson(const lab::ShapeLearning& learning);
// The same as text: the chosen shape's values at its knots, the formulas.
void PrintLearning(const lab::ShapeLearning& learning, std::ostream& out);

}  // namespace echoservo::apps
