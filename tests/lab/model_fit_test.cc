// The model lab's fit (lab/model_fit.h) on a dataset recorded in-process from
// the simulated catheter with seed + capstan_friction: it recovers the generating
// parameters, leaves only sensor noise, and its fixed-parameter evaluation agrees with it.
//
// Tolerances (parameters): |estimate − truth| < 5·SD + allowance. The SDs come from the
// fit's covariance scaled by the reduced χ², i.e. they account for the noise actually
// left; 5 SD makes a chance failure negligible. The allowance covers what the SD cannot:
// the lab's model is not the simulator. The simulator integrates friction at 10 kHz on
// the slide's true velocity, with inertia and stick-slip inside the servo loop; the lab
// predicts friction from a ±5 ms centred difference of the 1 µm-quantised encoder at
// 1 kHz, and treats the samples around reversals as "may stick". These are systematic,
// not random, so they do not shrink with more samples: we allow 1 % of the parameter's
// value. Measured on this dataset (seed 1): f0, μ_tip and the capstan μ are within 1.1 SD
// of the truth; b is 0.15 % (4.8 SD, SD = 0.03 %) high — the viscous term is the one that
// sees the velocity estimate and the stick-slip at low speed. 1 % is 6× that bias and
// still an order of magnitude below what a real mistake (a lost factor, a capstan term
// applied to the wrong angle) does to a parameter. No truth here is near zero.
#include "lab/model_fit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "hw/effect_registry.h"
#include "tests/lab/lab_test_util.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::lab {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;
using testing::Record;
using testing::Recording;
using testing::TruthParameters;

std::vector<std::string> Spec(const std::string& s) {
  return hw::ParseModelSpec(s, hw::EffectRegistry::WithBuiltinEffects());
}

class ModelFit : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    Recording r;
    r.effects = "seed+capstan_friction";
    dataset_ = new LabDataset(Record(r));
  }
  static void TearDownTestSuite() {
    delete dataset_;
    dataset_ = nullptr;
  }
  static const LabDataset& dataset() { return *dataset_; }
  static LabDataset* dataset_;
};
LabDataset* ModelFit::dataset_ = nullptr;

TEST_F(ModelFit, RecoversTheGeneratingParameters) {
  const LabDataset& ds = dataset();
  ASSERT_EQ(ds.trials.size(), 16u);
  const std::map<std::string, double> truth = TruthParameters(ds);
  const FitResult fit = FitModel(Spec("seed+capstan_friction"), ds, FitOptions{});
  ASSERT_EQ(fit.estimates.size(), 4u);
  for (const ParameterEstimate& e : fit.estimates) {
    ASSERT_TRUE(truth.contains(e.name)) << e.name;
    const double t = truth.at(e.name);
    const double allowance = 0.01 * std::abs(t);
    EXPECT_LT(std::abs(e.value - t), 5.0 * e.sd + allowance)
        << e.name << ": estimate " << e.value << " ± " << e.sd << " " << e.unit << ", truth " << t;
    // Identifiable parameters (the lab's configurations vary load and bend) have finite,
    // positive standard deviations, small against the value.
    EXPECT_TRUE(std::isfinite(e.sd)) << e.name;
    EXPECT_GT(e.sd, 0.0) << e.name;
    EXPECT_LT(e.sd, 0.05 * std::abs(t)) << e.name;
  }
  // What is left is the sensor noise: the tip RMS within 10 % of the tip noise estimated
  // from the data, and the force RMS within 20 % of the force noise (the force also
  // carries the simulator's stick-slip that the lab's kinematic prediction cannot follow).
  EXPECT_NEAR(fit.overall.tip_rms_mm, ds.noise.tip_mm, 0.1 * ds.noise.tip_mm);
  EXPECT_NEAR(fit.overall.force_rms_n, ds.noise.force_n, 0.2 * ds.noise.force_n);
  EXPECT_NEAR(fit.tip_mse_norm, 1.0, 0.21);
  ASSERT_EQ(fit.trials.size(), ds.trials.size());
  for (std::size_t k = 0; k < fit.trials.size(); ++k) {
    EXPECT_EQ(fit.trials[k].name, ds.trials[k].trial.name);
    EXPECT_EQ(fit.trials[k].prediction.tip_mm.size(), ds.trials[k].trial.size());
    EXPECT_GE(fit.trials[k].nuisance.contact, -1.0);
    EXPECT_LE(fit.trials[k].nuisance.contact, 1.0);
  }
  EXPECT_EQ(fit.overall.samples, 16u * 3000u);
}

TEST_F(ModelFit, TheSeedModelMissesTheCapstanFriction) {
  // Without the capstan term the friction level cannot follow the bend angle: the force
  // error is several times the noise, and the tip is unaffected (it is at the noise).
  const LabDataset& ds = dataset();
  const FitResult seed = FitModel(Spec("seed"), ds, FitOptions{});
  EXPECT_GT(seed.overall.force_rms_n, 5.0 * ds.noise.force_n);
  EXPECT_NEAR(seed.overall.tip_rms_mm, ds.noise.tip_mm, 0.1 * ds.noise.tip_mm);
}

TEST_F(ModelFit, EvaluateWithTheFittedParametersReproducesTheFit) {
  const LabDataset& ds = dataset();
  const std::vector<std::string> effects = Spec("seed+capstan_friction");
  const FitResult fit = FitModel(effects, ds, FitOptions{});
  const FitResult eval = EvaluateModel(effects, fit.parameters, ds, FitOptions{}, {});
  EXPECT_EQ(eval.parameters, fit.parameters);
  EXPECT_NEAR(eval.overall.tip_rms_mm, fit.overall.tip_rms_mm, 0.01 * fit.overall.tip_rms_mm);
  EXPECT_NEAR(eval.overall.force_rms_n, fit.overall.force_rms_n, 0.01 * fit.overall.force_rms_n);
  EXPECT_NEAR(eval.tip_mse_norm, fit.tip_mse_norm, 0.01 * fit.tip_mse_norm);
  EXPECT_NEAR(eval.force_mse_norm, fit.force_mse_norm, 0.01 * fit.force_mse_norm);
  ASSERT_EQ(eval.trials.size(), fit.trials.size());
  for (std::size_t k = 0; k < fit.trials.size(); ++k) {
    EXPECT_NEAR(eval.trials[k].stats.tip_rms_mm, fit.trials[k].stats.tip_rms_mm,
                0.01 * fit.trials[k].stats.tip_rms_mm)
        << fit.trials[k].name;
  }
  // Fixed parameters are reported without standard deviations.
  for (const ParameterEstimate& e : eval.estimates) EXPECT_TRUE(std::isnan(e.sd)) << e.name;

  // A subset evaluates only those trials, in the subset's order.
  const FitResult some = EvaluateModel(effects, fit.parameters, ds, FitOptions{}, {3, 1});
  ASSERT_EQ(some.trials.size(), 2u);
  EXPECT_EQ(some.trials[0].name, ds.trials[3].trial.name);
  EXPECT_EQ(some.trials[1].name, ds.trials[1].trial.name);
  EXPECT_NEAR(some.trials[0].stats.tip_rms_mm, fit.trials[3].stats.tip_rms_mm,
              0.01 * fit.trials[3].stats.tip_rms_mm);
}

TEST_F(ModelFit, RejectsUnknownEffectsAndWrongStartingValues) {
  const LabDataset& ds = dataset();
  ExpectContains(InvalidArgumentMessage([&] {
                   FitModel({"coulomb_friction", "warp_drive"}, ds, FitOptions{});
                 }),
                 "warp_drive");
  const std::vector<double> wrong(2, 0.5);
  ExpectContains(
      InvalidArgumentMessage([&] { FitModel(Spec("seed"), ds, FitOptions{}, {}, &wrong); }),
      "initial values");
}

TEST(ModelFitIdentifiability, ATermWithNoLeverIsReportedWithoutAnSd) {
  // One catheter without tip load: μ_tip multiplies a zero load, so nothing in the data
  // constrains it and its standard deviation is undefined (NaN), while f0 and b are fine.
  Recording r;
  r.configs = "seed";
  r.trajectories = {"sine:4:0.8"};
  r.duration_s = 2.0;
  const LabDataset ds = Record(r);
  ASSERT_EQ(ds.trials.size(), 1u);
  const FitResult fit = FitModel(Spec("seed"), ds, FitOptions{});
  for (const ParameterEstimate& e : fit.estimates) {
    if (e.name == "coulomb_friction.mu_tip") {
      EXPECT_TRUE(std::isnan(e.sd)) << e.sd;
    }
  }
  EXPECT_NEAR(fit.overall.tip_rms_mm, ds.noise.tip_mm, 0.1 * ds.noise.tip_mm);
}

}  // namespace
}  // namespace echoservo::lab
