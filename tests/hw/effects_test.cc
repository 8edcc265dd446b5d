// The effect catalog, the registry and the model SPEC grammar, and every catalog effect
// on its own against its equation (hw/effects/*.cc).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "hw/effect.h"
#include "hw/effect_registry.h"
#include "hw/effects/builtin_effects.h"
#include "hw/transmission_model.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::hw {
namespace {

using ::echoservo::testing::ExpectContains;
using ::echoservo::testing::InvalidArgumentMessage;

using Names = std::vector<std::string>;

const Names kCatalog = {"coulomb_friction",  "viscous_friction",     "stribeck_friction",
                        "capstan_friction",  "guidewire_compliance", "backlash",
                        "friction_backlash", "deadzone_traversal",   "sensor_delay",
                        "tip_sensor_scale"};

const EffectRegistry& BuiltinCatalog() {
  static const EffectRegistry registry = EffectRegistry::WithBuiltinEffects();
  return registry;
}

formats::CatheterConfig Geometry(double sheath_id_mm, double guidewire_od_mm,
                                 std::vector<double> bends_deg, double tip_load_n) {
  formats::CatheterConfig c;
  c.sheath_id_mm = sheath_id_mm;
  c.guidewire_od_mm = guidewire_od_mm;
  for (double a : bends_deg) c.bends.push_back({a, 30.0});
  c.tip_load_n = tip_load_n;
  return c;
}

double Deg(double deg) { return deg * std::numbers::pi / 180.0; }

// ---------------------------------------------------------------- registry and SPEC

TEST(EffectRegistry, BuiltinCatalogInPipelineOrder) {
  EXPECT_EQ(BuiltinCatalog().Names(), kCatalog);
  for (const std::string& name : kCatalog) {
    ASSERT_TRUE(BuiltinCatalog().Contains(name)) << name;
    const auto effect = BuiltinCatalog().Create(name);
    ASSERT_NE(effect, nullptr);
    EXPECT_EQ(effect->name(), name);
    EXPECT_FALSE(effect->description().empty()) << name;
    EXPECT_FALSE(effect->signature().empty()) << name;
    for (const ParameterSpec& p : effect->parameters()) {
      EXPECT_FALSE(p.name.empty()) << name;
      EXPECT_FALSE(p.unit.empty()) << name << "." << p.name;
      EXPECT_LT(p.lower, p.upper) << name << "." << p.name;
      EXPECT_GE(p.default_value, p.lower) << name << "." << p.name;
      EXPECT_LE(p.default_value, p.upper) << name << "." << p.name;
    }
  }
  EXPECT_FALSE(BuiltinCatalog().Contains("seed"));  // an alias of the SPEC grammar, not an effect
}

TEST(EffectRegistry, StagesMatchThePipeline) {
  const std::vector<std::pair<std::string, EffectStage>> expected = {
      {"coulomb_friction", EffectStage::kFriction},
      {"viscous_friction", EffectStage::kFriction},
      {"stribeck_friction", EffectStage::kFriction},
      {"capstan_friction", EffectStage::kFriction},
      {"guidewire_compliance", EffectStage::kCompliance},
      {"backlash", EffectStage::kBacklash},
      {"friction_backlash", EffectStage::kBacklash},
      {"deadzone_traversal", EffectStage::kTipDynamics},
      {"sensor_delay", EffectStage::kSensor},
      {"tip_sensor_scale", EffectStage::kSensor}};
  for (const auto& [name, stage] : expected) {
    EXPECT_EQ(BuiltinCatalog().Create(name)->stage(), stage) << name;
  }
  EXPECT_EQ(ToString(EffectStage::kTipDynamics), "tip dynamics");
}

TEST(EffectRegistry, UnknownEffectNamesTheTokenAndTheKnownOnes) {
  const std::string msg =
      InvalidArgumentMessage([] { BuiltinCatalog().Create("magnetic_friction"); });
  ExpectContains(msg, "magnetic_friction");
  ExpectContains(msg, "coulomb_friction");
  ExpectContains(msg, "seed");
}

TEST(EffectRegistry, RegisterRejectsBadEntries) {
  EffectRegistry r;
  EXPECT_THROW(r.Register("", MakeBacklash), std::invalid_argument);
  EXPECT_THROW(r.Register("backlash", nullptr), std::invalid_argument);
  ExpectContains(InvalidArgumentMessage([&] { r.Register("slack", MakeBacklash); }), "slack");
  r.Register("backlash", MakeBacklash);
  ExpectContains(InvalidArgumentMessage([&] { r.Register("backlash", MakeBacklash); }),
                 "registered twice");
  EXPECT_EQ(r.Names(), Names{"backlash"});
}

TEST(ModelSpec, SeedPlusCapstanExpandsInPipelineOrder) {
  const Names expected = {"coulomb_friction", "viscous_friction", "capstan_friction", "backlash"};
  EXPECT_EQ(ParseModelSpec("seed+capstan_friction", BuiltinCatalog()), expected);
  EXPECT_EQ(ParseModelSpec("capstan_friction+seed", BuiltinCatalog()), expected);
  EXPECT_EQ(ParseModelSpec("backlash+capstan_friction+viscous_friction+coulomb_friction",
                           BuiltinCatalog()),
            expected);
  EXPECT_EQ(ParseModelSpec("seed", BuiltinCatalog()), SeedEffects());
  EXPECT_EQ(SeedEffects(), (Names{"coulomb_friction", "viscous_friction", "backlash"}));
}

TEST(ModelSpec, FullCatalogInAnyOrderGivesPipelineOrder) {
  std::string reversed;
  for (auto it = kCatalog.rbegin(); it != kCatalog.rend(); ++it) {
    reversed += (reversed.empty() ? "" : "+") + *it;
  }
  EXPECT_EQ(ParseModelSpec(reversed, BuiltinCatalog()), kCatalog);
}

TEST(ModelSpec, UnknownTokenIsNamed) {
  for (const std::string token : {"magic", "Seed", "coulomb", " backlash", "backlash "}) {
    const std::string spec = "seed+" + token;
    const std::string msg = InvalidArgumentMessage([&] { ParseModelSpec(spec, BuiltinCatalog()); });
    ExpectContains(msg, "'" + token + "'");
  }
}

TEST(ModelSpec, EmptyTokensThrow) {
  EXPECT_THROW(ParseModelSpec("", BuiltinCatalog()), std::invalid_argument);
  for (const std::string spec : {"+", "seed+", "+seed", "seed++capstan_friction"}) {
    const std::string msg = InvalidArgumentMessage([&] { ParseModelSpec(spec, BuiltinCatalog()); });
    ExpectContains(msg, "'" + spec + "'");
    ExpectContains(msg, "empty");
  }
}

TEST(ModelSpec, DuplicatesThrowNamingTheEffect) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"seed+backlash", "backlash"},
      {"coulomb_friction+seed", "coulomb_friction"},
      {"sensor_delay+sensor_delay", "sensor_delay"},
      {"seed+seed", "coulomb_friction"}};
  for (const auto& [spec, dup] : cases) {
    const std::string msg =
        InvalidArgumentMessage([&spec = spec] { ParseModelSpec(spec, BuiltinCatalog()); });
    ExpectContains(msg, "'" + dup + "'");
    ExpectContains(msg, "twice");
  }
}

TEST(ModelSpec, FormatUsesTheSeedAlias) {
  EXPECT_EQ(FormatModelSpec(SeedEffects()), "seed");
  EXPECT_EQ(
      FormatModelSpec({"coulomb_friction", "viscous_friction", "capstan_friction", "backlash"}),
      "seed+capstan_friction");
  EXPECT_EQ(FormatModelSpec({"coulomb_friction", "backlash"}), "coulomb_friction+backlash");
}

TEST(ModelSpec, FormatParseRoundTripOverEveryCatalogSubset) {
  const std::size_t n = kCatalog.size();
  for (unsigned mask = 1; mask < (1u << n); ++mask) {
    Names effects;
    for (std::size_t i = 0; i < n; ++i) {
      if (mask & (1u << i)) effects.push_back(kCatalog[i]);
    }
    const std::string spec = FormatModelSpec(effects);
    ASSERT_EQ(ParseModelSpec(spec, BuiltinCatalog()), effects) << spec;
  }
}

// ------------------------------------------------------- each effect on its own
//
// Each effect is exercised through its hooks with a hand-made context, and through a
// TransmissionModel that holds only that effect (the neutral defaults of every other
// stage then show up as zero friction, zero width, no lag, unit sensor).

TEST(CoulombFriction, ConstantPlusTipLoadTerm) {
  const auto e = BuiltinCatalog().Create("coulomb_friction");
  const double p[] = {0.7, 0.45};  // f0_n, mu_tip
  for (double load : {0.0, 1.0, 4.0, 20.0}) {
    EffectContext c;
    c.tip_load_n = load;
    for (double v : {0.0, 0.5, 10.0, 300.0}) {  // independent of speed
      EXPECT_DOUBLE_EQ(e->FrictionMagnitudeN(v, c, p), 0.7 + 0.45 * load) << load << " " << v;
    }
    EXPECT_DOUBLE_EQ(e->FrictionScale(c, p), 1.0);
  }
  // Through a model, with the geometry's tip load.
  for (double load : {0.0, 2.5, 10.0}) {
    TransmissionModel m(BuiltinCatalog(), {"coulomb_friction"}, Geometry(1.6, 0.8, {90}, load));
    m.SetParameter("coulomb_friction.f0_n", 0.7);
    m.SetParameter("coulomb_friction.mu_tip", 0.45);
    EXPECT_DOUBLE_EQ(m.FrictionLevelN(), 0.7 + 0.45 * load);
    EXPECT_DOUBLE_EQ(m.FrictionMagnitudeN(25.0), 0.7 + 0.45 * load);
    EXPECT_DOUBLE_EQ(m.BacklashWidthMm(), 0.0);
    EXPECT_DOUBLE_EQ(m.DriveMm(3.0, 1.0), 3.0);
  }
}

TEST(ViscousFriction, ProportionalToSpeed) {
  TransmissionModel m(BuiltinCatalog(), {"viscous_friction"},
                      formats::CatheterConfig::SeedEvaluation());
  const double b = 0.02;
  m.SetParameter("viscous_friction.b_n_per_mm_s", b);
  EXPECT_DOUBLE_EQ(m.FrictionLevelN(), 0.0);  // no force at rest
  for (double v : {0.0, 1.0, 7.5, 40.0, 250.0}) {
    EXPECT_NEAR(m.FrictionMagnitudeN(v), b * v, 1e-12 * (1.0 + v)) << v;
  }
  // Linear: doubling the speed doubles the force.
  EXPECT_NEAR(m.FrictionMagnitudeN(60.0), 2.0 * m.FrictionMagnitudeN(30.0), 1e-12);
}

TEST(StribeckFriction, FullAtRestFadesAboveTheStribeckSpeed) {
  TransmissionModel m(BuiltinCatalog(), {"stribeck_friction"},
                      formats::CatheterConfig::SeedEvaluation());
  const double df = 0.8;
  const double vs = 4.0;
  m.SetParameter("stribeck_friction.delta_static_n", df);
  m.SetParameter("stribeck_friction.v_stribeck_mm_s", vs);
  EXPECT_DOUBLE_EQ(m.FrictionLevelN(), df);  // the whole extra force at rest
  EXPECT_DOUBLE_EQ(m.FrictionMagnitudeN(0.0), df);
  EXPECT_NEAR(m.FrictionMagnitudeN(vs), df * std::exp(-1.0), 1e-12);
  EXPECT_NEAR(m.FrictionMagnitudeN(0.5 * vs), df * std::exp(-0.25), 1e-12);
  // At 3 v_s only exp(-9) ≈ 1.2e-4 of it is left.
  EXPECT_LT(m.FrictionMagnitudeN(3.0 * vs), 2e-4 * df);
  EXPECT_NEAR(m.FrictionMagnitudeN(3.0 * vs), df * std::exp(-9.0), 1e-15);
  // Monotonically decreasing with speed.
  double last = m.FrictionMagnitudeN(0.0);
  for (double v = 0.25; v < 20.0; v += 0.25) {
    const double f = m.FrictionMagnitudeN(v);
    EXPECT_LT(f, last) << v;
    last = f;
  }
}

TEST(CapstanFriction, MultipliesAllFrictionByExpMuTheta) {
  const double mu = 0.25;
  for (const std::vector<double>& bends :
       {std::vector<double>{}, {45.0}, {90.0, 90.0}, {180.0, 90.0, 90.0}, {360.0, 360.0}}) {
    const formats::CatheterConfig g = Geometry(1.6, 0.8, bends, 0.0);
    const double theta = g.TotalBendRad();
    TransmissionModel m(BuiltinCatalog(),
                        {"coulomb_friction", "viscous_friction", "capstan_friction"}, g);
    m.SetParameter("capstan_friction.mu", mu);
    const double f0 = m.GetParameter("coulomb_friction.f0_n");
    const double b = m.GetParameter("viscous_friction.b_n_per_mm_s");
    for (double v : {0.0, 10.0, 50.0}) {
      EXPECT_NEAR(m.FrictionMagnitudeN(v), (f0 + b * v) * std::exp(mu * theta), 1e-12)
          << "theta=" << theta << " v=" << v;
    }
    EXPECT_NEAR(m.FrictionLevelN(), f0 * std::exp(mu * theta), 1e-12);
  }
  // On its own it scales nothing: no friction to amplify.
  TransmissionModel alone(BuiltinCatalog(), {"capstan_friction"},
                          formats::CatheterConfig::SeedEvaluation());
  EXPECT_DOUBLE_EQ(alone.FrictionMagnitudeN(10.0), 0.0);
  // Hook: the factor itself.
  const auto e = BuiltinCatalog().Create("capstan_friction");
  EffectContext c;
  c.total_bend_rad = Deg(270.0);
  const double p[] = {0.4};
  EXPECT_NEAR(e->FrictionScale(c, p), std::exp(0.4 * Deg(270.0)), 1e-12);
  EXPECT_DOUBLE_EQ(e->FrictionMagnitudeN(5.0, c, p), 0.0);
}

TEST(GuidewireCompliance, DriveIsBaseMinusForceOverStiffness) {
  TransmissionModel m(BuiltinCatalog(), {"guidewire_compliance"},
                      formats::CatheterConfig::SeedEvaluation());
  for (double k : {0.5, 5.0, 200.0}) {
    m.SetParameter("guidewire_compliance.k_n_per_mm", k);
    for (double base : {-10.0, 0.0, 12.5}) {
      for (double f : {-2.0, 0.0, 0.3, 1.5}) {
        EXPECT_NEAR(m.DriveMm(base, f), base - f / k, 1e-12) << k << " " << base << " " << f;
      }
    }
  }
  EXPECT_DOUBLE_EQ(m.FrictionMagnitudeN(10.0), 0.0);
  EXPECT_DOUBLE_EQ(m.BacklashWidthMm(), 0.0);
}

TEST(Backlash, WidthIsThetaTimesGap) {
  for (const auto& [sheath, wire] : {std::pair{1.6, 0.8}, {1.2, 0.9}, {3.0, 0.5}}) {
    for (const std::vector<double>& bends :
         {std::vector<double>{}, {30.0}, {90.0, 90.0}, {120.0, 60.0, 45.0}}) {
      const formats::CatheterConfig g = Geometry(sheath, wire, bends, 0.0);
      TransmissionModel m(BuiltinCatalog(), {"backlash"}, g);
      double theta_deg = 0.0;
      for (double a : bends) theta_deg += a;
      EXPECT_NEAR(m.BacklashWidthMm(), Deg(theta_deg) * (sheath - wire), 1e-12)
          << sheath << "/" << wire << " theta=" << theta_deg;
    }
  }
  // The seed evaluation catheter: θ = π, gap 0.8 mm.
  TransmissionModel seed(BuiltinCatalog(), {"backlash"}, formats::CatheterConfig::SeedEvaluation());
  EXPECT_NEAR(seed.BacklashWidthMm(), std::numbers::pi * 0.8, 1e-12);
  // Width does not depend on friction.
  TransmissionModel loaded(BuiltinCatalog(), {"coulomb_friction", "backlash"},
                           Geometry(1.6, 0.8, {90.0, 90.0}, 10.0));
  EXPECT_NEAR(loaded.BacklashWidthMm(), std::numbers::pi * 0.8, 1e-12);
}

TEST(FrictionBacklash, WidthGrowsWithTheFrictionLevel) {
  const double a = 0.5;
  const double bpn = 0.2;
  for (double load : {0.0, 1.0, 5.0, 20.0}) {
    const formats::CatheterConfig g = Geometry(1.6, 0.8, {90.0, 90.0}, load);
    TransmissionModel m(BuiltinCatalog(), {"coulomb_friction", "friction_backlash"}, g);
    m.SetParameter("friction_backlash.a", a);
    m.SetParameter("friction_backlash.b_per_n", bpn);
    const double level =
        m.GetParameter("coulomb_friction.f0_n") + m.GetParameter("coulomb_friction.mu_tip") * load;
    ASSERT_NEAR(m.FrictionLevelN(), level, 1e-12);
    EXPECT_NEAR(m.BacklashWidthMm(), std::numbers::pi * 0.8 * (a + bpn * level), 1e-12)
        << "load=" << load;
  }
  // The level is the breakaway friction: Stribeck counts, viscous (zero at rest) does not.
  TransmissionModel s(
      BuiltinCatalog(),
      {"coulomb_friction", "viscous_friction", "stribeck_friction", "friction_backlash"},
      formats::CatheterConfig::SeedEvaluation());
  const double level =
      s.GetParameter("coulomb_friction.f0_n") + s.GetParameter("stribeck_friction.delta_static_n");
  EXPECT_NEAR(s.BacklashWidthMm(),
              std::numbers::pi * 0.8 *
                  (s.GetParameter("friction_backlash.a") +
                   s.GetParameter("friction_backlash.b_per_n") * level),
              1e-12);
  // Without any friction effect only the zero-friction factor a remains.
  TransmissionModel bare(BuiltinCatalog(), {"friction_backlash"},
                         formats::CatheterConfig::SeedEvaluation());
  EXPECT_NEAR(bare.BacklashWidthMm(),
              std::numbers::pi * 0.8 * bare.GetParameter("friction_backlash.a"), 1e-12);
}

TEST(FrictionBacklash, ReplacesTheGeometricWidthInPipelineOrder) {
  const Names effects = ParseModelSpec("seed+friction_backlash", BuiltinCatalog());
  TransmissionModel m(BuiltinCatalog(), effects, formats::CatheterConfig::SeedEvaluation());
  const double factor = m.GetParameter("friction_backlash.a") +
                        m.GetParameter("friction_backlash.b_per_n") * m.FrictionLevelN();
  EXPECT_NEAR(m.BacklashWidthMm(), std::numbers::pi * 0.8 * factor, 1e-12);
  EXPECT_GT(std::abs(factor - 1.0), 0.05);  // distinguishable from θ·gap
}

TEST(DeadzoneTraversal, TimeConstantFromItsParameter) {
  const auto e = BuiltinCatalog().Create("deadzone_traversal");
  const double p[] = {0.07};
  EXPECT_DOUBLE_EQ(e->TraversalTimeConstantS(p), 0.07);
  TransmissionModel m(BuiltinCatalog(), {"backlash", "deadzone_traversal"},
                      formats::CatheterConfig::SeedEvaluation());
  m.SetParameter("deadzone_traversal.tau_s", 0.035);
  EXPECT_DOUBLE_EQ(m.TraversalTimeConstantS(), 0.035);
  TransmissionModel none(BuiltinCatalog(), {"backlash"}, formats::CatheterConfig::SeedEvaluation());
  EXPECT_DOUBLE_EQ(none.TraversalTimeConstantS(), 0.0);
}

TEST(DeadzoneTraversal, OneTimeConstantClosesSixtyThreePercentOfTheGap) {
  TransmissionModel m(BuiltinCatalog(), {"backlash", "deadzone_traversal"},
                      formats::CatheterConfig::SeedEvaluation());
  const double tau = 0.02;
  m.SetParameter("deadzone_traversal.tau_s", tau);
  const double half = 0.5 * m.BacklashWidthMm();
  const double drive = 5.0;
  const double edge = drive - half;  // the base pushed far ahead: the tip must reach this edge
  const double tip0 = 0.0;
  for (int steps : {1, 10, 200}) {  // the result must not depend on the step size
    const double dt = tau / steps;
    double tip = tip0;
    for (int i = 0; i < steps; ++i) tip = m.StepTip(tip, drive, dt);
    EXPECT_NEAR((tip - tip0) / (edge - tip0), 1.0 - std::exp(-1.0), 1e-12) << steps;
    for (int i = 0; i < 4 * steps; ++i) tip = m.StepTip(tip, drive, dt);  // 5 τ in all
    EXPECT_NEAR((tip - tip0) / (edge - tip0), 1.0 - std::exp(-5.0), 1e-12) << steps;
  }
  // Approaching from above (base pulled back) is symmetric.
  double tip = 10.0;
  const double upper = -3.0 + half;
  for (int i = 0; i < 20; ++i) tip = m.StepTip(tip, -3.0, tau / 20);
  EXPECT_NEAR((10.0 - tip) / (10.0 - upper), 1.0 - std::exp(-1.0), 1e-12);
}

TEST(DeadzoneTraversal, InsideTheBandTheTipDoesNotMove) {
  for (const Names& effects : {Names{"backlash"}, Names{"backlash", "deadzone_traversal"}}) {
    TransmissionModel m(BuiltinCatalog(), effects, formats::CatheterConfig::SeedEvaluation());
    const double half = 0.5 * m.BacklashWidthMm();
    for (double offset : {-0.99, -0.5, 0.0, 0.3, 0.99}) {
      const double tip = 2.0 + offset * half;
      EXPECT_EQ(m.StepTip(tip, 2.0, 1e-3), tip) << offset;
      EXPECT_EQ(m.StepTip(tip, 2.0, 1.0), tip) << offset;
    }
  }
}

TEST(DeadzoneTraversal, WithoutItTheTipJumpsToTheBandEdge) {
  TransmissionModel m(BuiltinCatalog(), {"backlash"}, formats::CatheterConfig::SeedEvaluation());
  const double half = 0.5 * m.BacklashWidthMm();
  EXPECT_DOUBLE_EQ(m.StepTip(0.0, 5.0, 1e-4), 5.0 - half);
  EXPECT_DOUBLE_EQ(m.StepTip(0.0, -5.0, 1e-4), -5.0 + half);
  // And with no deadzone at all the tip is the drive.
  TransmissionModel rigid(BuiltinCatalog(), {"coulomb_friction"},
                          formats::CatheterConfig::SeedEvaluation());
  EXPECT_DOUBLE_EQ(rigid.StepTip(0.0, 5.0, 1e-4), 5.0);
  EXPECT_DOUBLE_EQ(rigid.StepTip(3.0, -1.25, 1e-4), -1.25);
}

TEST(SensorDelay, DelayFromItsParameter) {
  const auto e = BuiltinCatalog().Create("sensor_delay");
  const double p[] = {0.012};
  EXPECT_DOUBLE_EQ(e->SensorDelayS(p), 0.012);
  EXPECT_DOUBLE_EQ(e->SensorScale(p), 1.0);
  TransmissionModel m(BuiltinCatalog(), {"sensor_delay"},
                      formats::CatheterConfig::SeedEvaluation());
  m.SetParameter("sensor_delay.delay_s", 0.03);
  EXPECT_DOUBLE_EQ(m.SensorDelayS(), 0.03);
  EXPECT_DOUBLE_EQ(m.SensorScale(), 1.0);
}

TEST(TipSensorScale, GainFromItsParameter) {
  const auto e = BuiltinCatalog().Create("tip_sensor_scale");
  const double p[] = {0.9};
  EXPECT_DOUBLE_EQ(e->SensorScale(p), 0.9);
  EXPECT_DOUBLE_EQ(e->SensorDelayS(p), 0.0);
  TransmissionModel m(BuiltinCatalog(), {"tip_sensor_scale"},
                      formats::CatheterConfig::SeedEvaluation());
  m.SetParameter("tip_sensor_scale.scale", 1.2);
  EXPECT_DOUBLE_EQ(m.SensorScale(), 1.2);
  EXPECT_DOUBLE_EQ(m.SensorDelayS(), 0.0);
}

TEST(Effects, NeutralHooksOfEveryEffect) {
  // Each effect changes only its own stage: every other hook keeps its neutral value.
  EffectContext c;
  c.total_bend_rad = 2.0;
  c.gap_mm = 0.5;
  c.tip_load_n = 3.0;
  for (const std::string& name : kCatalog) {
    const auto e = BuiltinCatalog().Create(name);
    std::vector<double> p;
    for (const ParameterSpec& s : e->parameters()) p.push_back(s.default_value);
    const double* pp = p.empty() ? nullptr : p.data();
    const EffectStage st = e->stage();
    const bool friction_term =
        name == "coulomb_friction" || name == "viscous_friction" || name == "stribeck_friction";
    if (!friction_term) {
      EXPECT_EQ(e->FrictionMagnitudeN(5.0, c, pp), 0.0) << name;
    }
    if (name != "capstan_friction") {
      EXPECT_EQ(e->FrictionScale(c, pp), 1.0) << name;
    }
    if (st != EffectStage::kCompliance) {
      EXPECT_EQ(e->DriveOffsetMm(1.5, c, pp), 0.0) << name;
    }
    if (st != EffectStage::kBacklash) {
      EXPECT_EQ(e->BacklashWidthMm(0.7, 1.0, c, pp), 0.7) << name;
    }
    if (st != EffectStage::kTipDynamics) {
      EXPECT_EQ(e->TraversalTimeConstantS(pp), 0.0) << name;
    }
    if (name != "sensor_delay") {
      EXPECT_EQ(e->SensorDelayS(pp), 0.0) << name;
    }
    if (name != "tip_sensor_scale") {
      EXPECT_EQ(e->SensorScale(pp), 1.0) << name;
    }
  }
}

}  // namespace
}  // namespace echoservo::hw
