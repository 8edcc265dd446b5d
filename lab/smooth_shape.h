// Learned shapes: a smooth function of one variable or of a pair, learnt from samples by
// penalised least squares, with the penalty weight chosen by cross-validation.
//
// The function is piecewise linear between knots (a hat / degree-1 B-spline basis; a pair
// is the tensor product, bilinear in each cell), and its values at the knots are the
// unknowns. The fit minimises Σ_i w_i·(y_i − m_i·f(x_i) − Σ_j b_j·n_ij − g_{group(i)})² +
// λ·Σ (second differences of the knot values along each axis)², where m_i is an optional
// per-sample multiplier (the direction of motion for a friction-like term, a signature
// scale), n_ij optional nuisance columns fitted with it unpenalised (what the physical model
// already absorbs: Coulomb and viscous friction) and g an optional free constant per group
// (a per-trial sensor offset). λ is chosen from `lambdas` by the held-out mean square over
// the caller's folds (trials for catheter data, time blocks for motion traces); the shape
// is then refitted on every sample with that λ. Outside its knots the shape is held at the
// end values (Evaluate) — a tabulated effect file refuses such inputs instead
// (hw/effect_file.h).
// Units: the shape's value is in the target's unit divided by the multiplier's; gains in the
// target's unit squared (noise variances when the target is a residual in noise σ).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace echoservo::lab {

struct ShapeAxis {
  std::string variable;       // e.g. "base_mm", "bend_deg"
  std::vector<double> knots;  // strictly increasing, at least 2
};

struct SmoothShape {
  std::vector<ShapeAxis> axes;  // 1 or 2
  // At the knots; for a pair row-major with axes[0] slowest: values[i0·n1 + i1].
  std::vector<double> values;
  double lambda = 0.0;          // chosen penalty weight
  double held_out_gain = 0.0;   // held-out mean square removed at that λ (target units²)
  double held_out_mse = 0.0;    // held-out mean square left
  double in_sample_gain = 0.0;  // mean square removed on every sample after the refit

  // Linear (bilinear) interpolation, held at the end values outside the knots.
  double Evaluate(double x) const;
  double Evaluate(double x, double y) const;
  // One sample's inputs, one per axis.
  double Evaluate(const double* inputs) const;
};

// The hat functions that are non-zero at one sample's inputs (one per axis): writes up to 4
// (value index, weight) pairs and returns how many; the weights sum to 1 (inputs outside the
// knots are held at the end knots).
int ShapeBasis(const std::vector<ShapeAxis>& axes, const double* inputs, std::size_t* columns,
               double* weights);

// `count` knots at the quantiles of `x` (the first and last at its minimum and maximum),
// fewer when x has fewer distinct values (then its distinct values). Strictly increasing;
// at least 2 knots when x holds two distinct values, 1 when it holds one.
std::vector<double> QuantileKnots(const std::vector<double>& x, int count);

struct ShapeFitOptions {
  std::vector<double> lambdas = {1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0};
  // λ is scaled by the samples' total weight, so the same λ smooths alike on any data size.
  bool scale_lambda_by_weight = true;
};

// The samples a shape is learnt from. `inputs[a][i]` is axis a's variable at sample i.
// Optional (empty): `multiplier` (1), `weight` (1), `nuisance` (none), `group` (none).
// Samples with a negative fold take part in the final fit but in no held-out score.
struct ShapeSamples {
  std::vector<std::vector<double>> inputs;
  std::vector<double> target;
  std::vector<double> multiplier;
  std::vector<double> weight;
  std::vector<std::vector<double>> nuisance;  // columns, each of the samples' length
  std::vector<std::size_t> group;             // free constant per group
  std::vector<int> fold;                      // 0..folds−1; at least 2 folds used
};

// Learns the shape over `axes` (knots given). Throws std::invalid_argument naming the
// problem (inconsistent lengths, fewer than 2 folds, an axis with fewer than 2 knots or
// unsorted knots, more than 2 axes).
SmoothShape FitSmoothShape(const std::vector<ShapeAxis>& axes, const ShapeSamples& samples,
                           const ShapeFitOptions& options = {});

}  // namespace echoservo::lab
