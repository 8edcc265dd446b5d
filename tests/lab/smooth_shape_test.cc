#include "lab/smooth_shape.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

namespace echoservo::lab {
namespace {

// Samples along x in [−10, 10] mm of `law` plus Gaussian noise σ = 1, in 8 groups (trials),
// each with its own constant offset, dealt into 2 folds by group.
ShapeSamples Make(double (*law)(double), bool with_offsets, unsigned seed, bool signed_motion) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> where(-10.0, 10.0);
  ShapeSamples s;
  s.inputs.resize(1);
  for (std::size_t g = 0; g < 8; ++g) {
    const double offset = with_offsets ? 3.0 * (static_cast<double>(g) - 3.5) : 0.0;
    for (int k = 0; k < 1500; ++k) {
      const double x = where(rng);
      const double dir = signed_motion ? (k % 2 == 0 ? 1.0 : -1.0) : 1.0;
      s.inputs[0].push_back(x);
      s.multiplier.push_back(dir);
      s.target.push_back(dir * law(x) + offset + noise(rng));
      s.group.push_back(g);
      s.fold.push_back(static_cast<int>(g % 2));
    }
  }
  if (!with_offsets) s.group.clear();
  return s;
}

double Ripple(double x) { return 2.0 * std::sin(2.0 * M_PI * x / 7.0); }
double Nothing(double) { return 0.0; }

TEST(SmoothShape, LearnsAPeriodicShapeWithDirectionAndTrialOffsets) {
  const ShapeSamples s = Make(&Ripple, true, 1, true);
  const std::vector<ShapeAxis> axes = {{"base_mm", QuantileKnots(s.inputs[0], 25)}};
  const SmoothShape shape = FitSmoothShape(axes, s);
  // The ripple's mean square is 2 (amplitude 2): nearly all of it is removed on held-out
  // groups, and what is left is the unit noise.
  EXPECT_GT(shape.held_out_gain, 1.8);
  EXPECT_LT(shape.held_out_mse, 1.1);
  // The shape matches the law between the knots within the spline's and the noise's error
  // (its mean is free: the group offsets absorb a constant only where multiplier is 1, so
  // compare after removing the mean).
  double err2 = 0.0, mean = 0.0;
  int count = 0;
  for (double x = -9.5; x <= 9.5; x += 0.25) {
    mean += shape.Evaluate(x) - Ripple(x);
    ++count;
  }
  mean /= count;
  for (double x = -9.5; x <= 9.5; x += 0.25)
    err2 += std::pow(shape.Evaluate(x) - Ripple(x) - mean, 2);
  EXPECT_LT(std::sqrt(err2 / count), 0.15);
}

TEST(SmoothShape, PureNoiseGainsNothingOnHeldOutData) {
  const ShapeSamples s = Make(&Nothing, true, 2, false);
  const SmoothShape shape = FitSmoothShape({{"x", QuantileKnots(s.inputs[0], 20)}}, s);
  // Noise alone: the learnt function only adds its own error on data it was not fitted to
  // (a gain below 0.01 noise variances), and the penalty makes it nearly flat.
  EXPECT_LT(shape.held_out_gain, 0.01);
  for (double v : shape.values) EXPECT_LT(std::abs(v), 0.2);
}

TEST(SmoothShape, LearnsAProductOfTwoVariables) {
  // y = 0.02·bend·v: a trial-level variable (3 bends) times a sample-level one.
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> speed(-100.0, 100.0);
  ShapeSamples s;
  s.inputs.resize(2);
  const double bends[] = {90.0, 180.0, 270.0};
  for (std::size_t g = 0; g < 6; ++g) {
    for (int k = 0; k < 2000; ++k) {
      const double b = bends[g % 3];
      const double v = speed(rng);
      s.inputs[0].push_back(b);
      s.inputs[1].push_back(v);
      s.target.push_back(0.0002 * b * v + noise(rng));
      s.fold.push_back(static_cast<int>(g / 3));
    }
  }
  const std::vector<ShapeAxis> axes = {{"bend_deg", QuantileKnots(s.inputs[0], 4)},
                                       {"velocity_mm_s", QuantileKnots(s.inputs[1], 8)}};
  ASSERT_EQ(axes[0].knots.size(), 3u);
  const SmoothShape shape = FitSmoothShape(axes, s);
  EXPECT_NEAR(shape.Evaluate(270.0, 80.0), 0.0002 * 270.0 * 80.0, 0.15);
  EXPECT_NEAR(shape.Evaluate(90.0, -50.0), 0.0002 * 90.0 * -50.0, 0.15);
  EXPECT_GT(shape.held_out_gain, 0.9 * (0.0002 * 0.0002 * (90 * 90 + 180 * 180 + 270 * 270) / 3.0 *
                                        100.0 * 100.0 / 3.0));
}

TEST(SmoothShape, RefusesInconsistentInput) {
  ShapeSamples s;
  s.inputs = {{1.0, 2.0, 3.0}};
  s.target = {1.0, 2.0, 3.0};
  s.fold = {0, 1, 0};
  EXPECT_THROW(FitSmoothShape({{"x", {1.0, 1.0, 3.0}}}, s), std::invalid_argument);
  EXPECT_THROW(FitSmoothShape({{"x", {1.0, 3.0}}, {"y", {1.0, 3.0}}}, s), std::invalid_argument);
  s.fold = {0, 0, 0};
  EXPECT_THROW(FitSmoothShape({{"x", {1.0, 3.0}}}, s), std::invalid_argument);
  s.fold = {0, 1};
  EXPECT_THROW(FitSmoothShape({{"x", {1.0, 3.0}}}, s), std::invalid_argument);
}

TEST(SmoothShape, QuantileKnotsSpanTheDataAndKeepFewDistinctValues) {
  const std::vector<double> few = {3.0, 1.0, 2.0, 2.0, 1.0};
  EXPECT_EQ(QuantileKnots(few, 8), (std::vector<double>{1.0, 2.0, 3.0}));
  std::vector<double> many;
  for (int i = 0; i <= 1000; ++i) many.push_back(i * 0.01);
  const std::vector<double> k = QuantileKnots(many, 11);
  ASSERT_EQ(k.size(), 11u);
  EXPECT_DOUBLE_EQ(k.front(), 0.0);
  EXPECT_DOUBLE_EQ(k.back(), 10.0);
  EXPECT_NEAR(k[5], 5.0, 1e-9);
}

}  // namespace
}  // namespace echoservo::lab
