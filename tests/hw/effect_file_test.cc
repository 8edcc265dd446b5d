// Effect files (hw/effect_file.h) and the signal hooks (hw/effect.h) they reach.
//
// Ground truths: a file effect that writes a built-in's equation must give that built-in's
// numbers (one multiplication each way: equal to 1e-12, in fact bit for bit); the signal
// hooks' contributions are exact functions of the trial's own signals (m·a, d·t, a bump in
// base position), so they are checked against those formulas to 1e-12. In the simulated
// catheter, an inertial force m·a of the guidewire makes the slide accelerate as a mass
// M + m would (Newton, the fixed point of the substep recursion a_k = (F − f0 − m·a_{k−1})/M,
// which contracts by m/M = 0.2 per substep).
#include "hw/effect_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include "hw/effect_registry.h"
#include "hw/simulated_catheter.h"
#include "hw/transmission_model.h"
#include "lab/lab_dataset.h"
#include "lab/model_prediction.h"
#include "tests/hw/effect_test_util.h"
#include "tests/hw/whole_trial_hooks.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::hw {
namespace {

using ::echoservo::testing::ExpectContains;
using ::echoservo::testing::InvalidArgumentMessage;
using Names = std::vector<std::string>;
using testing::SineTrial;

constexpr double kTight = 1e-12;

std::string EffectText(const std::string& name, const std::string& params,
                       const std::string& exprs) {
  return R"j({"format": "echoservo.effect/1", "name": ")j" + name +
         R"j(", "description": "test effect", "parameters": [)j" + params +
         R"j(], "expressions": {)j" + exprs + "}}";
}

const std::string kViscousParam =
    R"j({"name": "c_n_per_mm_s", "unit": "N/(mm/s)", "default": 0.006, "lower": 0, "upper": 0.1})j";

class EffectFileTest : public testing::ScratchFileTest {
 protected:
  // Registers `text` (written to `file`) in the registry.
  void Add(const std::string& file, const std::string& text) {
    RegisterEffectSpec(registry_, ReadEffectFile(Write(file, text)));
  }
  EffectRegistry registry_ = EffectRegistry::WithBuiltinEffects();
};

lab::Prediction Predict(const EffectRegistry& r, const Names& effects,
                        const std::vector<std::pair<std::string, double>>& set = {}) {
  static const lab::LabTrial trial = SineTrial();
  TransmissionModel m(r, effects, trial.trial.config);
  for (const auto& [k, v] : set) m.SetParameter(k, v);
  lab::Prediction p;
  lab::PredictTrial(m, trial, {0.1, 0.3}, p);
  return p;
}

void ExpectSamePrediction(const lab::Prediction& a, const lab::Prediction& b) {
  ASSERT_EQ(a.tip_mm.size(), b.tip_mm.size());
  for (std::size_t i = 0; i < a.tip_mm.size(); ++i) {
    ASSERT_NEAR(a.tip_mm[i], b.tip_mm[i], kTight) << i;
    ASSERT_NEAR(a.force_n[i], b.force_n[i], kTight) << i;
  }
}

// ------------------------------------------------------------ reproducing a built-in

TEST_F(EffectFileTest, FileViscousFrictionPredictsAsTheBuiltin) {
  Add("v.json",
      EffectText("file_viscous", kViscousParam, R"j("friction_n": "c_n_per_mm_s*speed_mm_s")j"));
  // The same through the signal path (time_s makes it a signal hook contributing 0·t).
  Add("vs.json", EffectText("file_viscous_signal", kViscousParam,
                            R"j("friction_n": "c_n_per_mm_s*speed_mm_s + 0*time_s")j"));
  const auto builtin = Predict(registry_, {"coulomb_friction", "viscous_friction", "backlash"});
  const auto file = Predict(registry_, {"coulomb_friction", "backlash", "file_viscous"});
  const auto signal = Predict(registry_, {"coulomb_friction", "backlash", "file_viscous_signal"});
  ExpectSamePrediction(builtin, file);
  ExpectSamePrediction(builtin, signal);
  TransmissionModel m(registry_, {"coulomb_friction", "file_viscous"},
                      formats::CatheterConfig::SeedEvaluation());
  EXPECT_FALSE(m.UsesSignals());
  ExpectWholeTrialHooksMatchPerSample(m);
  TransmissionModel s(registry_, {"file_viscous_signal"},
                      formats::CatheterConfig::SeedEvaluation());
  EXPECT_TRUE(s.UsesSignals());
}

std::vector<std::array<double, 3>> RunSine(const EffectRegistry& r, const Names& effects,
                                           bool noise) {
  return testing::RunPlantSine(r, effects, noise);
}

TEST_F(EffectFileTest, FileViscousFrictionSimulatesAsTheBuiltin) {
  Add("v.json",
      EffectText("file_viscous", kViscousParam, R"j("friction_n": "c_n_per_mm_s*speed_mm_s")j"));
  Add("vs.json", EffectText("file_viscous_signal", kViscousParam,
                            R"j("friction_n": "c_n_per_mm_s*speed_mm_s + 0*time_s")j"));
  const auto a = RunSine(registry_, {"coulomb_friction", "viscous_friction", "backlash"}, true);
  const auto b = RunSine(registry_, {"coulomb_friction", "backlash", "file_viscous"}, true);
  const auto c = RunSine(registry_, {"coulomb_friction", "backlash", "file_viscous_signal"}, true);
  EXPECT_GT(std::abs(a.back()[2] - a.front()[2]) + std::abs(a[100][2]), 0.1);  // it moved
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_NEAR(a[i][k], b[i][k], kTight) << i;
      ASSERT_NEAR(a[i][k], c[i][k], kTight) << i;
    }
  }
}

// ------------------------------------------------------------------ signal hooks

TEST_F(EffectFileTest, InertiaForceAddsMassTimesAccelerationToThePredictedForce) {
  Add("m.json",
      EffectText("guidewire_inertia",
                 R"j({"name": "m_kg", "unit": "kg", "default": 0.05, "lower": 0, "upper": 1})j",
                 R"j("force_n": "m_kg*acceleration_mm_s2*1e-3")j"));
  const lab::LabTrial trial = SineTrial();
  const auto a = Predict(registry_, {"viscous_friction"});
  const auto b = Predict(registry_, {"viscous_friction", "guidewire_inertia"});
  TransmissionModel m(registry_, {"viscous_friction"}, trial.trial.config);
  int stick = 0;
  for (std::size_t i = 0; i < trial.trial.size(); ++i) {
    const double extra = 0.05 * trial.acceleration_mm_s2[i] * 1e-3;
    ASSERT_NEAR(b.tip_mm[i], a.tip_mm[i], kTight);  // the drive sees friction only
    if (trial.may_stick[i] == 0) {
      ASSERT_NEAR(b.force_n[i] - a.force_n[i], extra, kTight) << i;
    } else {
      ++stick;
      const double band = m.FrictionMagnitudeN(std::abs(trial.velocity_mm_s[i]));
      ASSERT_NEAR(b.force_n[i], extra + std::clamp(trial.trial.force_n[i] - extra, -band, band),
                  kTight);
    }
  }
  EXPECT_GT(stick, 0);
}

TEST_F(EffectFileTest, DriftOffsetGrowsWithTrialTime) {
  Add("d.json",
      EffectText(
          "sensor_drift",
          R"j({"name": "d_mm_per_s", "unit": "mm/s", "default": 0.2, "lower": -1, "upper": 1})j",
          R"j("sensor_offset_mm": "d_mm_per_s*time_s")j"));
  const lab::LabTrial trial = SineTrial();
  const auto a = Predict(registry_, {"coulomb_friction", "backlash", "sensor_delay"});
  const auto b =
      Predict(registry_, {"coulomb_friction", "backlash", "sensor_delay", "sensor_drift"});
  for (std::size_t i = 0; i < trial.trial.size(); ++i) {
    ASSERT_NEAR(b.tip_mm[i] - a.tip_mm[i], 0.2 * (trial.trial.t_s[i] - trial.trial.t_s[0]), kTight);
    ASSERT_EQ(b.force_n[i], a.force_n[i]);
  }
  EXPECT_EQ(registry_.Create("sensor_drift")->stage(), EffectStage::kSensor);
}

const std::string kBumpParams =
    R"j({"name": "a_n", "unit": "N", "default": 0.5, "lower": 0, "upper": 5},
       {"name": "x0_mm", "unit": "mm", "default": 2, "lower": -20, "upper": 20},
       {"name": "w_mm", "unit": "mm", "default": 1, "lower": 0.01, "upper": 10})j";
const std::string kBump = R"j("friction_n": "a_n*exp(-((base_mm-x0_mm)/w_mm)^2)")j";

double Bump(double base_mm) { return 0.5 * std::exp(-std::pow((base_mm - 2.0) / 1.0, 2)); }

TEST_F(EffectFileTest, PositionFrictionBumpFollowsTheBase) {
  Add("b.json", EffectText("tight_spot", kBumpParams, kBump));
  const lab::LabTrial trial = SineTrial();
  const auto a = Predict(registry_, {"coulomb_friction", "viscous_friction"});
  const auto b = Predict(registry_, {"coulomb_friction", "viscous_friction", "tight_spot"});
  int in_bump = 0;
  for (std::size_t i = 0; i < trial.trial.size(); ++i) {
    if (trial.may_stick[i] != 0) continue;
    const double bump = Bump(trial.trial.base_mm[i]);
    in_bump += bump > 0.25 ? 1 : 0;
    ASSERT_NEAR(b.force_n[i] - a.force_n[i], std::copysign(bump, trial.velocity_mm_s[i]), kTight);
  }
  EXPECT_GT(in_bump, 100);
  TransmissionModel m(registry_, {"coulomb_friction", "tight_spot"}, trial.trial.config);
  EXPECT_TRUE(m.UsesSignals());
  SampleSignals at_bump;
  at_bump.base_mm = 2.0;
  EXPECT_NEAR(m.BreakawayN(at_bump), m.FrictionLevelN() + 0.5, kTight);
  EXPECT_EQ(m.BreakawayN(SampleSignals{}), m.FrictionLevelN() + Bump(0.0));
}

// In the simulated catheter: a force between f0 and f0 + a_n holds the slide at the bump
// and not away from it.
TEST_F(EffectFileTest, PositionFrictionBumpHoldsTheSimulatedSlide) {
  Add("b.json", EffectText("tight_spot", kBumpParams, kBump));
  PlantOptions o;
  o.effects = {"coulomb_friction", "tight_spot"};
  o.registry = &registry_;
  o.sensor_noise = false;
  for (const double start : {2.0, 12.0}) {
    SimulatedCatheter plant(o);
    plant.ResetTo(start);
    plant.Configure();
    plant.Activate();
    const double force = plant.model().FrictionLevelN() + 0.3;
    for (int i = 0; i < 20; ++i) {
      plant.read(1e-3 * i, 1e-3);
      plant.set_command(0, force);
      plant.write(1e-3 * i, 1e-3);
    }
    if (start == 2.0) {
      EXPECT_EQ(plant.truth().base_mm, 2.0);
    } else {
      EXPECT_GT(plant.truth().base_mm, start + 0.1);
    }
  }
}

TEST_F(EffectFileTest, SimulatedInertiaAddsToTheMovingMass) {
  Add("m.json",
      EffectText("guidewire_inertia",
                 R"j({"name": "m_kg", "unit": "kg", "default": 0.05, "lower": 0, "upper": 1})j",
                 R"j("force_n": "m_kg*acceleration_mm_s2*1e-3")j"));
  PlantOptions o;
  o.effects = {"coulomb_friction", "guidewire_inertia"};
  o.registry = &registry_;
  o.sensor_noise = false;
  o.sensors.force_quantum_n = 0.0;
  SimulatedCatheter plant(o);
  plant.Configure();
  plant.Activate();
  const double f = 3.0;
  const double f0 = plant.model().FrictionLevelN();
  for (int i = 0; i < 30; ++i) {
    plant.read(1e-3 * i, 1e-3);
    plant.set_command(0, f);
    plant.write(1e-3 * i, 1e-3);
  }
  plant.read(0.03, 1e-3);
  const double mass = o.actuator.moving_mass_kg + 0.05;
  const double a = (f - f0) / mass * 1000.0;  // mm/s²
  EXPECT_NEAR(plant.truth().acceleration_mm_s2, a, 1e-6 * a);
  EXPECT_NEAR(plant.truth().time_s, 0.03, 1e-12);
  // The force sensor reads friction plus the inertial force.
  EXPECT_NEAR(plant.state(iface::kSensorForce), f0 + 0.05 * a * 1e-3, 1e-6);
}

TEST_F(EffectFileTest, SimulatedDriftGrowsWithTimeSinceReset) {
  Add("d.json",
      EffectText(
          "sensor_drift",
          R"j({"name": "d_mm_per_s", "unit": "mm/s", "default": 0.2, "lower": -1, "upper": 1})j",
          R"j("sensor_offset_mm": "d_mm_per_s*time_s")j"));
  PlantOptions o;
  o.registry = &registry_;
  o.sensor_noise = false;
  o.sensors.tip_quantum_mm = 0.0;
  o.effects = {"coulomb_friction", "viscous_friction", "backlash"};
  SimulatedCatheter a(o);
  o.effects.push_back("sensor_drift");
  SimulatedCatheter b(o);
  for (SimulatedCatheter* p : {&a, &b}) {
    p->Configure();
    p->Activate();
  }
  for (int i = 0; i < 300; ++i) {
    const double t = 1e-3 * i;
    const double cmd = 2.0 * std::sin(2.0 * std::numbers::pi * 2.0 * t);
    for (SimulatedCatheter* p : {&a, &b}) {
      p->read(t, 1e-3);
      p->set_command(0, cmd);
    }
    ASSERT_NEAR(b.state(iface::kTipPosition) - a.state(iface::kTipPosition), 0.2 * b.truth().time_s,
                kTight);
    ASSERT_EQ(a.truth().base_mm, b.truth().base_mm);
    for (SimulatedCatheter* p : {&a, &b}) p->write(t, 1e-3);
  }
  EXPECT_NEAR(b.truth().time_s, 0.3, 1e-9);
}

// --------------------------------------------------------------------- the format

TEST_F(EffectFileTest, ReadsEveryFieldAndDerivesTheStage) {
  const std::string path = Write("t.json", EffectText("tight_spot", kBumpParams, kBump));
  const EffectFileSpec s = ReadEffectFile(path);
  EXPECT_EQ(s.name, "tight_spot");
  EXPECT_EQ(s.description, "test effect");
  EXPECT_EQ(s.path, path);
  ASSERT_EQ(s.parameters.size(), 3u);
  EXPECT_EQ(s.parameters[2].name, "w_mm");
  EXPECT_EQ(s.parameters[2].lower, 0.01);
  ASSERT_EQ(s.expressions.size(), 1u);
  EXPECT_EQ(s.expressions[0].first, "friction_n");
  const auto e = MakeExpressionEffect(s);
  EXPECT_EQ(e->stage(), EffectStage::kFriction);
  EXPECT_TRUE(e->UsesSignals());
}

TEST_F(EffectFileTest, WriteReadRoundTripAndSpecSyntax) {
  EffectFileSpec s = ReadEffectFile(Write("t.json", EffectText("tight_spot", kBumpParams, kBump)));
  s.signature = "a bump in the force residual at one base position";
  s.parameters[0].doc = "height";
  const std::string path = (dir_ / "written.json").string();
  WriteEffectFile(path, s);
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  const EffectFileSpec r = ReadEffectFile(path);
  EXPECT_EQ(r.name, s.name);
  EXPECT_EQ(r.description, s.description);
  EXPECT_EQ(r.signature, s.signature);
  EXPECT_EQ(r.expressions, s.expressions);
  ASSERT_EQ(r.parameters.size(), s.parameters.size());
  for (std::size_t i = 0; i < r.parameters.size(); ++i) {
    EXPECT_EQ(r.parameters[i].name, s.parameters[i].name);
    EXPECT_EQ(r.parameters[i].unit, s.parameters[i].unit);
    EXPECT_EQ(r.parameters[i].default_value, s.parameters[i].default_value);
    EXPECT_EQ(r.parameters[i].lower, s.parameters[i].lower);
    EXPECT_EQ(r.parameters[i].upper, s.parameters[i].upper);
    EXPECT_EQ(r.parameters[i].doc, s.parameters[i].doc);
  }
  EXPECT_EQ(EffectJson(r), EffectJson(s));

  const Names names = ResolveModelSpec("@" + path + "+seed", registry_);
  EXPECT_EQ(names, (Names{"coulomb_friction", "viscous_friction", "backlash", "tight_spot"}));
  EXPECT_EQ(registry_.Source("tight_spot"), path);
  EXPECT_EQ(registry_.Source("backlash"), "");
  const std::string spec = FormatModelSpec(names, registry_);
  EXPECT_EQ(spec, "seed+@" + path);
  EXPECT_EQ(ResolveModelSpec(spec, registry_), names);  // the same file again: reused
}

TEST_F(EffectFileTest, SpecRejectsANameFromAnotherFileOrTheCatalog) {
  const std::string a = Write("a.json", EffectText("tight_spot", kBumpParams, kBump));
  const std::string b = Write("b.json", EffectText("tight_spot", kBumpParams, kBump));
  ResolveModelSpec("seed+@" + a, registry_);
  const std::string m = InvalidArgumentMessage([&] { ResolveModelSpec("seed+@" + b, registry_); });
  ExpectContains(m, a);
  ExpectContains(m, b);
  ExpectContains(InvalidArgumentMessage([&] { ResolveModelSpec("seed+@", registry_); }), "'@'");
  ExpectContains(InvalidArgumentMessage([&] { ResolveModelSpec("@" + a + "x", registry_); }),
                 "cannot read");
}

struct BadCase {
  std::string text;
  std::string key;
  std::string why;
};

TEST_F(EffectFileTest, EveryBadInputNamesTheFileTheKeyAndWhy) {
  const std::string p0 =
      R"j({"name": "a_n", "unit": "N", "default": 0.3, "lower": 0, "upper": 5})j";
  const std::string good = R"j("friction_n": "a_n")j";
  const std::vector<BadCase> cases = {
      {R"j({"format": "echoservo.effect/1",)j", "line 1", "invalid JSON"},
      {R"j({"format": "echoservo.effect/1", "name": "x", "parameters": []})j", "",
       "missing key 'expressions'"},
      {R"j({"format": "echoservo.effect/1", "name": "x", "colour": 1, "parameters": [], )j"
       R"j("expressions": {"friction_n": "1"}})j",
       "colour", "unknown key"},
      {R"j({"format": "echoservo.effect/2", "name": "x", "parameters": [], )j"
       R"j("expressions": {"friction_n": "1"}})j",
       "format", "not supported"},
      {EffectText("Tight-Spot", p0, good), "name", "lowercase"},
      {EffectText("backlash", p0, good), "name", "catalog effect"},
      {EffectText("x", p0, R"j("friction_n": "a_n*(speed_mm_s")j"), "expressions.friction_n",
       "position"},
      {EffectText("x", p0, R"j("friction_n": "a_n*speed")j"), "expressions.friction_n",
       "unknown variable 'speed'"},
      {EffectText("x", p0, R"j("friction_n": "foo(a_n)")j"), "expressions.friction_n",
       "unknown function 'foo'"},
      {EffectText("x", p0, R"j("friction": "a_n")j"), "expressions.friction",
       "unknown hook (known: friction_n, friction_scale"},
      {EffectText("x", p0, R"j("friction_n": "a_n/(speed_mm_s-10)")j"), "expressions.friction_n",
       "inf"},
      {EffectText("x", p0, R"j("friction_scale": "sqrt(a_n-1)")j"), "expressions.friction_scale",
       "nan"},
      {EffectText("x", R"j({"name": "a_n", "unit": "", "default": 0.3, "lower": 0, "upper": 5})j",
                  good),
       "parameters[0].unit", "must not be empty"},
      {EffectText("x", R"j({"name": "a_n", "default": 0.3, "lower": 0, "upper": 5})j", good),
       "parameters[0]", "missing key 'unit'"},
      {EffectText("x",
                  p0 + R"j(, {"name": "b_n", "unit": "N", "default": 1, "lower": 1, "upper": 1})j",
                  good),
       "parameters[1].upper", "greater than lower"},
      {EffectText("x", R"j({"name": "a_n", "unit": "N", "default": 7, "lower": 0, "upper": 5})j",
                  good),
       "parameters[0].default", "outside the bounds"},
      {EffectText("x", p0 + ", " + p0, good), "parameters[1].name", "duplicate"},
      {EffectText("x",
                  R"j({"name": "base_mm", "unit": "mm", "default": 0, "lower": -1, "upper": 1})j",
                  good),
       "parameters[0].name", "shadows an input"},
      {EffectText("x",
                  R"j({"name": "a_n", "unit": "N", "default": "0.3", "lower": 0, "upper": 5})j",
                  good),
       "parameters[0].default", "must be a number"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string path = Write("bad" + std::to_string(i) + ".json", cases[i].text);
    std::string message;
    try {
      ReadEffectFile(path);
      ADD_FAILURE() << "case " << i << " was accepted: " << cases[i].text;
      continue;
    } catch (const EffectFileError& e) {
      message = e.what();
    }
    SCOPED_TRACE("case " + std::to_string(i));
    ExpectContains(message, path + ": ");
    ExpectContains(message, cases[i].key);
    ExpectContains(message, cases[i].why);
  }
  const std::string missing = (dir_ / "none.json").string();
  ExpectContains(InvalidArgumentMessage([&] { ReadEffectFile(missing); }), missing);
}

}  // namespace
}  // namespace echoservo::hw
