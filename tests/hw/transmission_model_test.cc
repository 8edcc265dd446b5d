// TransmissionModel: parameter naming and validation, and the composition of effects
// into the pipeline friction → drive → deadzone → tip → sensor.
#include "hw/transmission_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/hw/whole_trial_hooks.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::hw {
namespace {

using ::echoservo::testing::ExpectContains;
using ::echoservo::testing::InvalidArgumentMessage;

using Names = std::vector<std::string>;

const EffectRegistry& Builtins() {
  static const EffectRegistry registry = EffectRegistry::WithBuiltinEffects();
  return registry;
}

TransmissionModel FullCatalog(
    const formats::CatheterConfig& config = formats::CatheterConfig::SeedEvaluation()) {
  return TransmissionModel(Builtins(), Builtins().Names(), config);
}

TEST(TransmissionModel, QualifiedParameterNamesInEffectOrder) {
  const TransmissionModel m = FullCatalog();
  const Names expected = {"coulomb_friction.f0_n",
                          "coulomb_friction.mu_tip",
                          "viscous_friction.b_n_per_mm_s",
                          "stribeck_friction.delta_static_n",
                          "stribeck_friction.v_stribeck_mm_s",
                          "capstan_friction.mu",
                          "guidewire_compliance.k_n_per_mm",
                          "friction_backlash.a",
                          "friction_backlash.b_per_n",
                          "deadzone_traversal.tau_s",
                          "sensor_delay.delay_s",
                          "tip_sensor_scale.scale"};
  ASSERT_EQ(m.parameter_info().size(), expected.size());
  ASSERT_EQ(m.parameters().size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const ParameterInfo& info = m.parameter_info()[i];
    EXPECT_EQ(info.qualified_name, expected[i]);
    // The qualified name is "<effect>.<parameter>" of the effect it belongs to.
    EXPECT_EQ(info.qualified_name, m.effect_names()[info.effect_index] + "." + info.spec.name);
  }
  EXPECT_EQ(m.effect_names(), Builtins().Names());
  EXPECT_TRUE(m.HasEffect("backlash"));  // no parameters, still part of the model
  EXPECT_FALSE(m.HasEffect("seed"));
}

TEST(TransmissionModel, DefaultsAreTheSpecDefaultsAndWithinBounds) {
  const TransmissionModel m = FullCatalog();
  for (std::size_t i = 0; i < m.parameters().size(); ++i) {
    const ParameterInfo& info = m.parameter_info()[i];
    EXPECT_EQ(m.parameters()[i], info.spec.default_value) << info.qualified_name;
    EXPECT_EQ(m.GetParameter(info.qualified_name), info.spec.default_value) << info.qualified_name;
    EXPECT_GE(info.spec.default_value, info.spec.lower) << info.qualified_name;
    EXPECT_LE(info.spec.default_value, info.spec.upper) << info.qualified_name;
    EXPECT_TRUE(std::isfinite(info.spec.lower) && std::isfinite(info.spec.upper));
  }
  // Divisors are bounded away from zero, so no parameter value can divide by zero.
  for (const char* divisor : {"stribeck_friction.v_stribeck_mm_s",
                              "guidewire_compliance.k_n_per_mm", "deadzone_traversal.tau_s"}) {
    for (const ParameterInfo& info : m.parameter_info()) {
      if (info.qualified_name == divisor) {
        EXPECT_GT(info.spec.lower, 0.0) << divisor;
      }
    }
  }
}

TEST(TransmissionModel, SetParameterAcceptsTheBoundsAndRejectsBeyond) {
  TransmissionModel m = FullCatalog();
  for (const ParameterInfo& info : std::vector<ParameterInfo>(m.parameter_info())) {
    const std::string& name = info.qualified_name;
    const double span = info.spec.upper - info.spec.lower;
    EXPECT_NO_THROW(m.SetParameter(name, info.spec.lower)) << name;
    EXPECT_EQ(m.GetParameter(name), info.spec.lower);
    EXPECT_NO_THROW(m.SetParameter(name, info.spec.upper)) << name;
    EXPECT_EQ(m.GetParameter(name), info.spec.upper);
    const std::vector<double> before = m.parameters();
    for (double bad :
         {info.spec.lower - 1e-3 * span, info.spec.upper + 1e-3 * span,
          std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
      const std::string msg = InvalidArgumentMessage([&] { m.SetParameter(name, bad); });
      ExpectContains(msg, "'" + name + "'");
      EXPECT_EQ(m.parameters(), before) << "a rejected value must leave the model unchanged";
    }
    m.SetParameter(name, info.spec.default_value);
  }
}

TEST(TransmissionModel, UnknownParameterNamesThrow) {
  TransmissionModel m(Builtins(), {"coulomb_friction", "backlash"},
                      formats::CatheterConfig::SeedEvaluation());
  // Unqualified, misspelt, or of an effect that is not in this model.
  for (const std::string name : {"f0_n", "coulomb_friction.f0", "coulomb_friction.",
                                 "viscous_friction.b_n_per_mm_s", "backlash.width", ""}) {
    ExpectContains(InvalidArgumentMessage([&] { m.SetParameter(name, 1.0); }), "'" + name + "'");
    ExpectContains(InvalidArgumentMessage([&] { m.GetParameter(name); }), "'" + name + "'");
  }
}

TEST(TransmissionModel, SetParametersChecksSizeAndValues) {
  TransmissionModel m(Builtins(), {"coulomb_friction", "viscous_friction", "backlash"},
                      formats::CatheterConfig::SeedEvaluation());
  ASSERT_EQ(m.parameters().size(), 3u);
  const std::string msg = InvalidArgumentMessage([&] { m.set_parameters({1.0, 0.1}); });
  ExpectContains(msg, "expected 3");
  ExpectContains(msg, "got 2");
  EXPECT_THROW(m.set_parameters({1.0, 0.1, 0.01, 0.0}), std::invalid_argument);
  EXPECT_THROW(m.set_parameters({}), std::invalid_argument);
  ExpectContains(InvalidArgumentMessage([&] {
                   m.set_parameters({1.0, -0.1, 0.01});
                 }),
                 "'coulomb_friction.mu_tip'");
  m.set_parameters({2.0, 0.5, 0.01});
  EXPECT_EQ(m.parameters(), (std::vector<double>{2.0, 0.5, 0.01}));
  EXPECT_DOUBLE_EQ(m.FrictionLevelN(), 2.0);  // the derived quantities follow
  EXPECT_NEAR(m.FrictionMagnitudeN(10.0), 2.0 + 0.1, 1e-12);
  // A parameterless model takes an empty vector.
  TransmissionModel b(Builtins(), {"backlash"}, formats::CatheterConfig::SeedEvaluation());
  EXPECT_NO_THROW(b.set_parameters({}));
  EXPECT_THROW(b.set_parameters({0.0}), std::invalid_argument);
}

TEST(TransmissionModel, ConstructorRejectsUnknownDuplicateAndBadGeometry) {
  ExpectContains(InvalidArgumentMessage([] {
                   TransmissionModel(Builtins(), {"coulomb_friction", "sticky"},
                                     formats::CatheterConfig::SeedEvaluation());
                 }),
                 "'sticky'");
  ExpectContains(InvalidArgumentMessage([] {
                   TransmissionModel(Builtins(), {"backlash", "backlash"},
                                     formats::CatheterConfig::SeedEvaluation());
                 }),
                 "'backlash'");
  formats::CatheterConfig bad = formats::CatheterConfig::SeedEvaluation();
  bad.guidewire_od_mm = 2.0;
  ExpectContains(InvalidArgumentMessage([&] { TransmissionModel(Builtins(), {"backlash"}, bad); }),
                 "guidewire_od_mm");
  TransmissionModel m(Builtins(), {"backlash"}, formats::CatheterConfig::SeedEvaluation());
  EXPECT_THROW(m.set_config(bad), std::invalid_argument);
  EXPECT_NEAR(m.BacklashWidthMm(), std::numbers::pi * 0.8, 1e-12);  // unchanged
}

TEST(TransmissionModel, EmptyModelIsAnIdealTransmission) {
  const TransmissionModel m(Builtins(), {}, formats::CatheterConfig::SeedEvaluation());
  EXPECT_TRUE(m.parameters().empty());
  EXPECT_EQ(m.FrictionMagnitudeN(20.0), 0.0);
  EXPECT_EQ(m.FrictionLevelN(), 0.0);
  EXPECT_EQ(m.DriveMm(4.0, 3.0), 4.0);
  EXPECT_EQ(m.BacklashWidthMm(), 0.0);
  EXPECT_EQ(m.StepTip(1.0, 4.0, 1e-3), 4.0);
  EXPECT_EQ(m.SensorDelayS(), 0.0);
  EXPECT_EQ(m.SensorScale(), 1.0);
}

TEST(TransmissionModel, FullCatalogComposesEveryStage) {
  formats::CatheterConfig g = formats::CatheterConfig::SeedEvaluation();
  g.tip_load_n = 2.0;
  const TransmissionModel m = FullCatalog(g);
  auto p = [&](const char* name) { return m.GetParameter(name); };
  const double theta = std::numbers::pi;
  const double capstan = std::exp(p("capstan_friction.mu") * theta);
  auto friction = [&](double v) {
    const double r = v / p("stribeck_friction.v_stribeck_mm_s");
    return (p("coulomb_friction.f0_n") + p("coulomb_friction.mu_tip") * g.tip_load_n +
            p("viscous_friction.b_n_per_mm_s") * v +
            p("stribeck_friction.delta_static_n") * std::exp(-r * r)) *
           capstan;
  };
  for (double v : {0.0, 1.0, 3.0, 20.0, 100.0})
    EXPECT_NEAR(m.FrictionMagnitudeN(v), friction(v), 1e-12);
  EXPECT_NEAR(m.FrictionLevelN(), friction(0.0), 1e-12);
  EXPECT_NEAR(m.DriveMm(1.0, 0.8), 1.0 - 0.8 / p("guidewire_compliance.k_n_per_mm"), 1e-12);
  // friction_backlash comes after backlash in the pipeline and replaces its width.
  EXPECT_NEAR(
      m.BacklashWidthMm(),
      theta * 0.8 * (p("friction_backlash.a") + p("friction_backlash.b_per_n") * friction(0.0)),
      1e-12);
  EXPECT_EQ(m.TraversalTimeConstantS(), p("deadzone_traversal.tau_s"));
  EXPECT_EQ(m.SensorDelayS(), p("sensor_delay.delay_s"));
  EXPECT_EQ(m.SensorScale(), p("tip_sensor_scale.scale"));
}

// The lab predicts whole trials through the batched hooks; the simulator steps per sample.
// Both must be the same model, for every catalog effect and for the seed alone.
TEST(TransmissionModel, WholeTrialHooksEqualThePerSampleCalls) {
  formats::CatheterConfig g = formats::CatheterConfig::SeedEvaluation();
  g.tip_load_n = 2.0;
  ExpectWholeTrialHooksMatchPerSample(FullCatalog(g));
  ExpectWholeTrialHooksMatchPerSample(
      TransmissionModel(Builtins(), Names{"coulomb_friction", "viscous_friction", "backlash"}, g));
  ExpectWholeTrialHooksMatchPerSample(TransmissionModel(Builtins(), Names{}, g));
}

TEST(TransmissionModel, SetConfigRefreshesTheDerivedQuantities) {
  TransmissionModel m(Builtins(), {"coulomb_friction", "capstan_friction", "backlash"},
                      formats::CatheterConfig::SeedEvaluation());
  formats::CatheterConfig g = formats::CatheterConfig::SeedEvaluation();
  g.bends = {{45.0, 20.0}};
  g.tip_load_n = 4.0;
  g.sheath_id_mm = 1.4;
  m.set_config(g);
  const double theta = std::numbers::pi / 4.0;
  const double level =
      (m.GetParameter("coulomb_friction.f0_n") + m.GetParameter("coulomb_friction.mu_tip") * 4.0) *
      std::exp(m.GetParameter("capstan_friction.mu") * theta);
  EXPECT_NEAR(m.FrictionLevelN(), level, 1e-12);
  EXPECT_NEAR(m.BacklashWidthMm(), theta * 0.6, 1e-12);
  EXPECT_EQ(m.config().tip_load_n, 4.0);
}

}  // namespace
}  // namespace echoservo::hw
