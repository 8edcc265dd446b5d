// A deadzone width that changes with the motion (hw/effect.h: SignalBacklashWidthMm), from an
// effect file's backlash_width_mm expression that reads a signal: a guidewire that lifts off
// the bend wall when fast, B(v) = θ·gap·(1 + |v|/v0).
//
// Ground truths: with v0 so large that |v|/v0 is below 1e-12 the per-sample width is the
// static seed width and the predictions and simulations agree with the seed's to 1e-9; at
// v0 = 60 mm/s the lag of the tip behind the drive on a constant-velocity ramp, once the
// deadzone is taken up, is hand-computed as ½·θ·gap·(1 + |v|/60) with θ·gap = π·0.8 mm (the
// seed evaluation catheter: 180° of bend, 0.8 mm gap).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "hw/effect_file.h"
#include "hw/effect_registry.h"
#include "hw/simulated_catheter.h"
#include "hw/transmission_model.h"
#include "lab/lab_dataset.h"
#include "lab/model_prediction.h"
#include "tests/hw/effect_test_util.h"

// A namespace of its own: the test target compiles in unity batches.
namespace echoservo::hw::signal_backlash_test {
namespace {

using Names = std::vector<std::string>;
using testing::SineTrial;

constexpr double kSeedWidthMm = std::numbers::pi * 0.8;  // θ·gap of the seed evaluation

// An effect file whose backlash_width_mm is `expr`, with parameter v0_mm_s (default `v0`).
EffectFileSpec Spec(const std::string& name, const std::string& expr, double v0 = 60.0) {
  return ParseEffectJson(
      R"j({"format": "echoservo.effect/1", "name": ")j" + name +
          R"j(", "parameters": [{"name": "v0_mm_s", "unit": "mm/s", "default": )j" +
          std::to_string(v0) + R"j(, "lower": 1, "upper": 1e15}],
          "expressions": {"backlash_width_mm": ")j" +
          expr + R"j("}})j",
      name + ".json");
}

EffectRegistry Registry(double v0) {
  EffectRegistry r = EffectRegistry::WithBuiltinEffects();
  RegisterEffectSpec(r, Spec("lift_off", "width_mm*(1+speed_mm_s/v0_mm_s)", v0));
  return r;
}

// A 1 s, 1 kHz ramp at `v` mm/s from -15 mm, at rest force.
lab::LabTrial RampTrial(double v) {
  formats::Trial t;
  t.name = "ramp";
  t.config = formats::CatheterConfig::SeedEvaluation();
  for (int i = 0; i < 1000; ++i) {
    const double ts = 1e-3 * i;
    t.t_s.push_back(ts);
    t.base_cmd_mm.push_back(-15.0 * std::copysign(1.0, v) + v * ts);
    t.base_mm.push_back(t.base_cmd_mm.back());
    t.tip_mm.push_back(t.base_cmd_mm.back());
    t.force_n.push_back(0.0);
  }
  return lab::PrepareLabDataset({t}).trials.front();
}

lab::Prediction Predict(const EffectRegistry& r, const Names& effects, const lab::LabTrial& trial,
                        const lab::TrialNuisance& nuisance) {
  TransmissionModel m(r, effects, trial.trial.config);
  lab::Prediction p;
  lab::PredictTrial(m, trial, nuisance, p);
  return p;
}

// Tip (truth and reading), base and force readings of a noiseless plant driven by a 3 N,
// 3 Hz sine for 0.4 s.
std::vector<std::array<double, 4>> RunSine(const EffectRegistry& r, const Names& effects) {
  PlantOptions o;
  o.effects = effects;
  o.registry = &r;
  o.sensor_noise = false;
  SimulatedCatheter plant(o);
  plant.Configure();
  plant.Activate();
  std::vector<std::array<double, 4>> out;
  for (int i = 0; i < 400; ++i) {
    const double t = 1e-3 * i;
    plant.read(t, 1e-3);
    out.push_back({plant.truth().tip_mm, plant.state(iface::kTipPosition),
                   plant.state(iface::kBasePosition), plant.state(iface::kSensorForce)});
    plant.set_command(0, 3.0 * std::sin(2.0 * std::numbers::pi * 3.0 * t));
    plant.write(t, 1e-3);
  }
  return out;
}

// (a) |v|/v0 negligible: the lab's prediction and the simulation equal the static seed's.
TEST(SignalBacklashTest, HugeLiftOffSpeedPredictsAndSimulatesAsTheStaticSeed) {
  const Names seed = {"coulomb_friction", "viscous_friction", "backlash"};
  Names lift = seed;
  lift.push_back("lift_off");
  // v0 = 1e12 mm/s: at the sine's 20 mm/s the width grows by 2.5e-11 mm. (With v0 = 1e9 it
  // would grow by up to ½·θ·gap·|v|/v0 ≈ 2.5e-8 mm, above 1e-9; checked against that bound.)
  const EffectRegistry r = Registry(1e12);
  TransmissionModel m(r, lift, formats::CatheterConfig::SeedEvaluation());
  EXPECT_TRUE(m.UsesSignalBacklash());
  EXPECT_FALSE(m.UsesSignals());
  EXPECT_EQ(m.BacklashWidthMm(), TransmissionModel(r, seed, m.config()).BacklashWidthMm());

  const lab::LabTrial trial = SineTrial();
  const lab::Prediction a = Predict(r, seed, trial, {0.1, 0.3});
  const lab::Prediction b = Predict(r, lift, trial, {0.1, 0.3});
  ASSERT_EQ(a.tip_mm.size(), b.tip_mm.size());
  for (std::size_t i = 0; i < a.tip_mm.size(); ++i) {
    ASSERT_NEAR(a.tip_mm[i], b.tip_mm[i], 1e-9) << i;
    ASSERT_EQ(a.force_n[i], b.force_n[i]) << i;
  }
  const lab::Prediction c = Predict(Registry(1e9), lift, trial, {0.1, 0.3});
  double max_speed = 0.0;
  for (const double v : trial.velocity_mm_s) max_speed = std::max(max_speed, std::abs(v));
  for (std::size_t i = 0; i < a.tip_mm.size(); ++i)
    ASSERT_LE(std::abs(a.tip_mm[i] - c.tip_mm[i]), 0.5 * kSeedWidthMm * max_speed / 1e9 + 1e-12);

  const auto sa = RunSine(r, seed);
  const auto sb = RunSine(r, lift);
  EXPECT_GT(std::abs(sa[100][2] - sa.front()[2]), 0.1);  // it moved
  for (std::size_t i = 0; i < sa.size(); ++i) {
    ASSERT_NEAR(sa[i][0], sb[i][0], 1e-9) << i;
    ASSERT_NEAR(sa[i][1], sb[i][1], 1e-9) << i;
    ASSERT_EQ(sa[i][2], sb[i][2]) << i;
    ASSERT_EQ(sa[i][3], sb[i][3]) << i;
  }
}

// (b) v0 = 60 mm/s: on a constant-velocity ramp, once the deadzone is taken up, the tip lags
// the drive (= base: no compliance) by half the speed-dependent width.
TEST(SignalBacklashTest, TipLagsARampByHalfTheSpeedDependentWidthInThePrediction) {
  const EffectRegistry r = Registry(60.0);
  for (const double v : {30.0, -45.0}) {
    const lab::LabTrial trial = RampTrial(v);
    const lab::Prediction p = Predict(r, {"backlash", "lift_off"}, trial, {0.0, 0.0});
    // ½·π·0.8·(1 + |v|/60): 0.6π mm at 30 mm/s, 0.7π mm at 45 mm/s.
    const double lag = (std::abs(v) == 30.0 ? 0.6 : 0.7) * std::numbers::pi;
    EXPECT_NEAR(lag, 0.5 * kSeedWidthMm * (1.0 + std::abs(v) / 60.0), 1e-12);
    // Taken up after lag/|v| ≤ 50 ms; checked from 0.1 s on.
    for (std::size_t i = 100; i < trial.trial.size(); ++i) {
      ASSERT_NEAR(trial.trial.base_mm[i] - p.tip_mm[i], std::copysign(lag, v), 1e-6)
          << "v = " << v << ", sample " << i;
    }
    // The static seed backlash lags by ½·θ·gap.
    const lab::Prediction s = Predict(r, {"backlash"}, trial, {0.0, 0.0});
    EXPECT_NEAR(trial.trial.base_mm[500] - s.tip_mm[500], std::copysign(0.4, v) * std::numbers::pi,
                1e-9);
    // The initial contact state takes the first sample's width: c = 1 puts the tip at
    // drive + ½·B(v).
    const lab::Prediction c = Predict(r, {"backlash", "lift_off"}, trial, {0.0, 1.0});
    EXPECT_NEAR(c.tip_mm[0] - trial.trial.base_mm[0], lag, 1e-6);
  }
}

TEST(SignalBacklashTest, TipLagsARampByHalfTheSpeedDependentWidthInTheSimulation) {
  const EffectRegistry r = Registry(60.0);
  PlantOptions o;
  o.effects = {"coulomb_friction", "viscous_friction", "backlash", "lift_off"};
  o.registry = &r;
  o.sensor_noise = false;
  SimulatedCatheter plant(o);
  plant.ResetTo(-24.0);
  plant.Configure();
  plant.Activate();
  ASSERT_TRUE(plant.model().UsesSignalBacklash());
  // Terminal velocity 30 mm/s: the drive force balances Coulomb plus viscous friction there
  // (the slide's viscous time constant m/c ≈ 42 ms; 0.6 s is over 14 of them).
  const double force = plant.model().FrictionLevelN() + 30.0 * plant.model().ViscousSlopeNPerMmS();
  for (int i = 0; i < 600; ++i) {
    plant.read(1e-3 * i, 1e-3);
    plant.set_command(0, force);
    plant.write(1e-3 * i, 1e-3);
    if (i < 500) continue;
    const PlantTruth& t = plant.truth();
    ASSERT_NEAR(t.base_velocity_mm_s, 30.0, 1e-3) << i;
    // Half the width at the substep's signals: the speed at the start of the last substep,
    // v − a·h (h = 0.1 ms), which differs from the final speed by the integration step.
    const double v_start = t.base_velocity_mm_s - t.acceleration_mm_s2 * 1e-4;
    ASSERT_NEAR(t.drive_mm - t.tip_mm, 0.5 * kSeedWidthMm * (1.0 + v_start / 60.0), 1e-12) << i;
    ASSERT_NEAR(t.drive_mm - t.tip_mm, 0.6 * std::numbers::pi, 1e-5) << i;
  }
}

// (c) A width from width_mm, friction level and geometry alone is one number per trial.
TEST(SignalBacklashTest, GeometryOnlyWidthStaysStatic) {
  EffectRegistry r = EffectRegistry::WithBuiltinEffects();
  RegisterEffectSpec(r, Spec("wide", "width_mm*(1+gap_mm/v0_mm_s)+0*friction_level_n*bend_rad"));
  const auto effect = r.Create("wide");
  EXPECT_FALSE(effect->UsesSignalBacklash());
  EXPECT_FALSE(effect->UsesSignals());
  EXPECT_EQ(effect->stage(), EffectStage::kBacklash);
  TransmissionModel m(r, {"backlash", "wide"}, formats::CatheterConfig::SeedEvaluation());
  EXPECT_FALSE(m.UsesSignalBacklash());
  EXPECT_NEAR(m.BacklashWidthMm(), kSeedWidthMm * (1.0 + 0.8 / 60.0), 1e-12);
  const SampleSignals fast{0.7, 3.0, -80.0, 500.0};
  EXPECT_EQ(m.BacklashWidthMm(fast), m.BacklashWidthMm());

  // The same width read per sample is a signal width (UsesSignalBacklash) and the static
  // hook passes the width unchanged.
  RegisterEffectSpec(r, Spec("lift_off", "width_mm*(1+speed_mm_s/v0_mm_s)"));
  const auto lift = r.Create("lift_off");
  EXPECT_TRUE(lift->UsesSignalBacklash());
  EXPECT_FALSE(lift->UsesSignals());
  const EffectContext c = EffectContext::From(formats::CatheterConfig::SeedEvaluation());
  const double p = 60.0;
  EXPECT_EQ(lift->BacklashWidthMm(2.0, 0.3, c, &p), 2.0);
  EXPECT_NEAR(lift->SignalBacklashWidthMm(2.0, 0.3, fast, c, &p), 2.0 * (1.0 + 80.0 / 60.0), 1e-12);
  TransmissionModel l(r, {"backlash", "lift_off"}, formats::CatheterConfig::SeedEvaluation());
  EXPECT_TRUE(l.UsesSignalBacklash());
  EXPECT_EQ(l.BacklashWidthMm(), kSeedWidthMm);
  EXPECT_NEAR(l.BacklashWidthMm(fast), kSeedWidthMm * (1.0 + 80.0 / 60.0), 1e-12);
}

// A table along a signal makes the width a signal width too; negative widths are 0; the
// whole-trial form equals the per-sample one bit for bit.
TEST(SignalBacklashTest, TableAlongSpeedAndNegativeWidthsAndWholeTrialForm) {
  EffectRegistry r = EffectRegistry::WithBuiltinEffects();
  RegisterEffectSpec(r, ParseEffectJson(R"j({"format": "echoservo.effect/1", "name": "tabled",
      "parameters": [],
      "tables": [{"name": "gain", "inputs": ["speed_mm_s"], "knots": [[0, 100]],
                  "values": [1, 3], "unit": "1", "lower": 0, "upper": 10}],
      "expressions": {"backlash_width_mm": "width_mm*gain"}})j",
                                        "tabled.json"));
  RegisterEffectSpec(r, Spec("shrink", "width_mm - 0.05*v0_mm_s*velocity_mm_s"));
  TransmissionModel m(r, {"backlash", "tabled"}, formats::CatheterConfig::SeedEvaluation());
  EXPECT_TRUE(m.UsesSignalBacklash());
  EXPECT_NEAR(m.BacklashWidthMm(SampleSignals{0.0, 0.0, -50.0, 0.0}), 2.0 * kSeedWidthMm, 1e-12);

  TransmissionModel s(r, {"backlash", "tabled", "shrink"},
                      formats::CatheterConfig::SeedEvaluation());
  // At +1 mm/s: π·0.8·1.02 − 3 < 0 → 0; at −1 mm/s: π·0.8·1.02 + 3.
  EXPECT_EQ(s.BacklashWidthMm(SampleSignals{0.0, 0.0, 1.0, 0.0}), 0.0);
  EXPECT_NEAR(s.BacklashWidthMm(SampleSignals{0.0, 0.0, -1.0, 0.0}), kSeedWidthMm * 1.02 + 3.0,
              1e-12);
  const std::vector<double> t = {0.0, 0.1, 0.2, 0.3, 0.4}, x = {0.0, 1.0, 2.0, -1.0, 4.0},
                            v = {-1.0, 1.0, 0.0, 20.0, -90.0}, a = {0.0, 5.0, -5.0, 1.0, 2.0};
  const TrialSignals sig{t, x, v, a};
  std::vector<double> widths(t.size());
  s.BacklashWidthsMm(sig, widths);
  for (std::size_t i = 0; i < t.size(); ++i)
    EXPECT_EQ(widths[i], s.BacklashWidthMm(sig.At(i))) << i;
  // Without signal backlash every sample has the static width.
  TransmissionModel plain(r, {"backlash"}, formats::CatheterConfig::SeedEvaluation());
  plain.BacklashWidthsMm(sig, widths);
  for (const double w : widths) EXPECT_EQ(w, plain.BacklashWidthMm());
}

}  // namespace
}  // namespace echoservo::hw::signal_backlash_test
