// Distilling a learned shape into a formula: a grammar of closed-form expressions over one
// variable or a pair, each with its constants fitted (Ceres, several starts), chosen by
// held-out error against complexity (the Pareto front).
//
// The grammar (form: expression in the variable x, or x and y for a pair; constants):
//   linear      c·x                              c
//   quadratic   c·x²                             c
//   cubic       c·x³                             c
//   power       c·|x|^p                          c, p ∈ [0.2, 4]
//   bump        a·exp(−((x − x0)/w)²)            a, x0, w
//   sine        a·sin(2π·x/P + φ)                a, P (period), φ (rad)
//   step        a/(1 + exp(−(x − x0)/w))         a, x0 (when), w (rise width, small)
//   ramp        a·w·ln(1 + exp((x − x0)/w))      a (slope), x0 (start), w (corner width)
//   exp_rise    a·(1 − exp(−x/τ))                a, τ
//   exp_decay   a·exp(−x/τ)                      a, τ
//   product     c·x·y                            c          (pairs only)
//   scaled      c·x·y² , c·x·|y|                 c          (pairs only)
// Every form also gets a free additive constant (`offset`, not counted in the complexity)
// when FormulaData::offset is set: what a physical model absorbs anyway (a Coulomb level, a
// sensor offset). Complexity = the number of fitted constants besides the offset.
// The held-out error is over the caller's folds (each fold predicted from constants fitted
// on the others); the reported constants are refitted on every sample.
// Units: each constant's unit follows the variables' and the target's (a period has x's
// unit, an amplitude the target's, a slope target/x, a phase rad).
#pragma once

#include <string>
#include <vector>

namespace echoservo::lab {

struct FormulaVariable {
  std::string name;  // as it appears in the expression, e.g. "base_mm"
  std::string unit;  // e.g. "mm"
};

struct FormulaData {
  std::vector<FormulaVariable> variables;   // 1, or 2 for the pair forms
  std::vector<std::vector<double>> inputs;  // inputs[v][i]
  std::vector<double> target;               // e.g. a learned shape's values at the samples
  std::vector<double> weight;               // optional (empty: 1)
  std::vector<int> fold;                    // 0..folds−1, at least 2 folds
  std::string target_unit;                  // e.g. "N"
  bool offset = true;                       // fit a free additive constant with every form
};

struct FormulaConstant {
  std::string name;  // parameter name usable in an effect file: [a-z][a-z0-9_]*
  std::string unit;
  double value = 0.0;
  std::string doc;  // "period along base_mm"
};

struct Formula {
  std::string form;  // "sine", "step", …
  int complexity = 0;
  std::vector<std::string> variables;
  std::vector<FormulaConstant> constants;
  double offset = 0.0;
  // muParser text over the variables' names and the constants' names (without the offset),
  // e.g. "a*sin(2*pi*base_mm/period+phase)".
  std::string expression;
  std::string words;          // with the fitted values and units
  double mse = 0.0;           // in sample (target units²)
  double held_out_mse = 0.0;  // over the folds
  // Value at one sample's inputs (one per variable), without the offset.
  double Evaluate(const double* inputs) const;
};

struct FormulaSearchOptions {
  std::vector<std::string> forms;  // empty: every form that fits the number of variables
  int starts = 6;                  // starting points per form for its nonlinear constants
};

// Fits every form of the grammar and scores it. Sorted by held-out error (best first).
// Throws std::invalid_argument naming the problem (inconsistent lengths, no variable, more
// than 2 variables, an unknown form, fewer than 2 folds).
std::vector<Formula> SearchFormulas(const FormulaData& data,
                                    const FormulaSearchOptions& options = {});

// The Pareto front of held-out error against complexity: the formulas, by increasing
// complexity, each with a lower held-out error than every simpler one kept.
std::vector<Formula> ParetoFront(const std::vector<Formula>& formulas);

}  // namespace echoservo::lab
