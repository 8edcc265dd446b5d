// What the catheter lab learnt about a term no library holds (lab/shape_learning.h): the
// shapes it screened and fitted through the whole model, the formulas the best shape was
// distilled into (the Pareto front of held-out error against complexity), and which of
// them it proposes.
// Units: a shape's values in its hook's unit (N for friction and force, mm for the tip
// sensor and drive offsets); held-out scores in noise variances of the channel.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "lab/formula_search.h"
#include "lab/smooth_shape.h"

namespace echoservo::lab {

struct LearnedShape {
  std::string hook;                    // "friction_n", "force_n", "sensor_offset_mm", …
  std::string channel;                 // "force" | "tip"
  std::vector<std::string> variables;  // the `where` variables (1, or a pair)
  std::vector<std::string> inputs;     // the hook's inputs they map to (speed_mm_s for a
                                       // friction magnitude along velocity)
  std::string unit;                    // of the values
  SmoothShape shape;                   // values in `unit`; through the model when fitted
  double screened_gain = 0.0;          // linearised held-out gain, noise variances
  bool fitted = false;                 // fitted through the whole model
  double tip_mse = NAN;                // held-out through the model, noise variances
  double force_mse = NAN;
  std::string Words() const;  // "friction magnitude (N) += shape(base_mm), 14 knots"
};

struct FormulaCandidate {
  Formula formula;       // fitted to the learned shape
  bool fitted = false;   // refitted through the whole model
  double tip_mse = NAN;  // held-out through the model, noise variances
  double force_mse = NAN;
  std::string equation;  // with the values fitted through the model
};

struct ShapeLearning {
  std::vector<LearnedShape> shapes;        // best screened first; shapes[0] is the chosen one
  std::vector<FormulaCandidate> formulas;  // the chosen shape's Pareto front
  std::string proposed;                    // "formula", "shape" or "" (nothing significant)
  std::string note;                        // why that one, in words
  bool empty() const { return shapes.empty(); }
};

}  // namespace echoservo::lab
