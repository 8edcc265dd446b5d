#include "apps/commands/lab_json.h"

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

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

namespace {

nlohmann::json Finite(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

std::string Fmt(double v, const char* format = "%.4g") {
  char buf[48];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace

nlohmann::json LearningJson(const lab::ShapeLearning& learning) {
  nlohmann::json shapes = nlohmann::json::array();
  for (const lab::LearnedShape& s : learning.shapes) {
    nlohmann::json knots = nlohmann::json::array();
    for (const lab::ShapeAxis& a : s.shape.axes) knots.push_back(a.knots);
    shapes.push_back({{"hook", s.hook},
                      {"channel", s.channel},
                      {"variables", s.variables},
                      {"inputs", s.inputs},
                      {"unit", s.unit},
                      {"knots", knots},
                      {"values", s.shape.values},
                      {"lambda", s.shape.lambda},
                      {"screened_gain_noise_var", s.screened_gain},
                      {"fitted_through_model", s.fitted},
                      {"cv_tip_mse_noise", Finite(s.tip_mse)},
                      {"cv_force_mse_noise", Finite(s.force_mse)},
                      {"words", s.Words()}});
  }
  nlohmann::json formulas = nlohmann::json::array();
  for (const lab::FormulaCandidate& f : learning.formulas) {
    nlohmann::json constants = nlohmann::json::array();
    for (const lab::FormulaConstant& c : f.formula.constants)
      constants.push_back({{"name", c.name}, {"unit", c.unit}, {"value", c.value}, {"doc", c.doc}});
    formulas.push_back({{"form", f.formula.form},
                        {"complexity", f.formula.complexity},
                        {"expression", f.formula.expression},
                        {"words", f.formula.words},
                        {"constants", constants},
                        {"shape_held_out_mse", Finite(f.formula.held_out_mse)},
                        {"fitted_through_model", f.fitted},
                        {"cv_tip_mse_noise", Finite(f.tip_mse)},
                        {"cv_force_mse_noise", Finite(f.force_mse)},
                        {"equation", f.equation}});
  }
  return {{"shapes", shapes},
          {"pareto_front", formulas},
          {"proposed",
           learning.proposed.empty() ? nlohmann::json() : nlohmann::json(learning.proposed)},
          {"note", learning.note}};
}

void PrintLearning(const lab::ShapeLearning& learning, std::ostream& out) {
  if (learning.empty()) return;
  const lab::LearnedShape& s = learning.shapes.front();
  out << "\nLearnt shape (" << s.Words() << ", held-out tip " << Fmt(std::sqrt(s.tip_mse), "%.2f")
      << "x, force " << Fmt(std::sqrt(s.force_mse), "%.2f") << "x the noise floor):\n";
  const auto& axes = s.shape.axes;
  if (axes.size() == 1) {
    out << "  " << axes[0].variable << " -> " << s.unit << "\n";
    for (std::size_t k = 0; k < axes[0].knots.size(); ++k)
      out << "  " << Fmt(axes[0].knots[k], "%10.4g") << "  " << Fmt(s.shape.values[k], "%10.4g")
          << "\n";
  } else {
    out << "  rows " << axes[0].variable << ", columns " << axes[1].variable << " -> " << s.unit
        << "\n  " << std::string(10, ' ');
    for (double k : axes[1].knots) out << Fmt(k, "%10.4g");
    out << "\n";
    for (std::size_t i = 0; i < axes[0].knots.size(); ++i) {
      out << "  " << Fmt(axes[0].knots[i], "%10.4g");
      for (std::size_t j = 0; j < axes[1].knots.size(); ++j)
        out << Fmt(s.shape.values[i * axes[1].knots.size() + j], "%10.4g");
      out << "\n";
    }
  }
  if (!learning.formulas.empty()) {
    out << "Formulas (Pareto front: held-out error against complexity):\n";
    for (const lab::FormulaCandidate& f : learning.formulas) {
      out << "  [" << f.formula.complexity << "] " << f.formula.form << ": " << f.formula.words;
      if (f.fitted)
        out << "  (through the model: held-out tip " << Fmt(std::sqrt(f.tip_mse), "%.2f")
            << "x, force " << Fmt(std::sqrt(f.force_mse), "%.2f") << "x noise)";
      out << "\n";
    }
  }
  out << "Proposed: " << (learning.proposed.empty() ? "nothing" : learning.proposed) << " — "
      << learning.note << "\n";
}

}  // namespace echoservo::apps
