// Adding a physical effect in one file, as docs/adding_an_effect.md shows it.
//
// The worked example `seal_preload_friction` (the O-ring of a hemostasis valve at the
// sheath's proximal port, squeezed onto the guidewire with a radial preload P, adds
// Coulomb friction mu_seal·P) is defined here exactly as the doc prints it: every block
// between "doc-example:begin" and "doc-example:end" must appear verbatim in the doc
// (checked by CustomEffect.DocShowsThisFilesExample). It is registered in a copy of the
// built-in registry and checked through the SPEC grammar, the TransmissionModel and the
// simulated catheter in closed loop.
//
// Tolerances: the force sensor has σ_F = 0.0075 N noise and a 0.002 N quantum
// (hw::SensorParams). The mean of n samples has a standard deviation σ/√n; as in
// tests/hw/simulated_catheter_test.cc we allow 4 of those plus half a quantum per mean
// (the largest bias rounding could add). A difference of two means is allowed
// 4·σ·√(2/n) plus one quantum.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <numbers>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "hw/effect.h"
#include "hw/effect_registry.h"
#include "hw/effects/builtin_effects.h"
#include "hw/simulated_catheter.h"
#include "hw/transmission_model.h"
#include "tests/hw/whole_trial_hooks.h"
#include "tests/test_util/constants.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::hw {
namespace {

using ::echoservo::testing::ExpectContains;
using ::echoservo::testing::InvalidArgumentMessage;

// doc-example:begin
class SealPreloadFriction final : public DescribedEffect {
 public:
  SealPreloadFriction()
      : DescribedEffect(
            "seal_preload_friction", EffectStage::kFriction,
            "Friction of the hemostasis valve at the sheath's proximal port: an O-ring "
            "squeezed onto the guidewire with a radial preload P grips it with Coulomb "
            "friction F = mu_seal*P, opposing sliding, independent of speed, bend angle, gap "
            "and tip load.",
            "force square wave raised by a constant mu_seal*P in every configuration: flat "
            "at constant speed, a step 2*mu_seal*P larger at every reversal, breakaway level "
            "raised by the same amount; from one preload alone indistinguishable from "
            "coulomb_friction.f0_n, it shows as a force offset that follows the valve preload "
            "between trials",
            {{"preload_n", "N", 2.0, 0.0, 20.0, "radial preload of the O-ring on the guidewire"},
             {"mu_seal", "1", 0.15, 0.0, 1.0, "O-ring to guidewire friction coefficient"}}) {}

 protected:
  double DoFrictionMagnitudeN(double, const EffectContext&, const double* p) const override {
    const double preload_n = p[0];
    const double mu_seal = p[1];
    return mu_seal * preload_n;
  }
};
// doc-example:end

// doc-example:begin
std::unique_ptr<Effect> MakeSealPreloadFriction() {
  return std::make_unique<SealPreloadFriction>();
}
// doc-example:end

// doc-example:begin
EffectRegistry RegistryWithSeal() {
  EffectRegistry r = EffectRegistry::WithBuiltinEffects();
  r.Register("seal_preload_friction", MakeSealPreloadFriction);
  return r;
}
// doc-example:end

using Names = std::vector<std::string>;

constexpr double kDefaultPreloadN = 2.0;
constexpr double kDefaultMuSeal = 0.15;

const EffectRegistry& Registry() {
  static const EffectRegistry registry = RegistryWithSeal();
  return registry;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return in ? s.str() : std::string();
}

// ----------------------------------------------------------------------- the doc

TEST(CustomEffect, DocShowsThisFilesExample) {
  const std::string doc =
      ReadText(std::string(ECHOSERVO_DATA_DIR) + "/../docs/adding_an_effect.md");
  ASSERT_FALSE(doc.empty()) << "cannot read docs/adding_an_effect.md";
  const std::string source = ReadText(__FILE__);
  ASSERT_FALSE(source.empty()) << "cannot read " << __FILE__;
  const std::string begin = std::string("// doc-example:") + "begin\n";
  const std::string end = std::string("// doc-example:") + "end\n";
  int blocks = 0;
  for (std::size_t at = source.find(begin); at != std::string::npos; at = source.find(begin, at)) {
    at += begin.size();
    const std::size_t stop = source.find(end, at);
    ASSERT_NE(stop, std::string::npos);
    const std::string block = source.substr(at, stop - at);
    EXPECT_NE(doc.find(block), std::string::npos)
        << "docs/adding_an_effect.md no longer shows this block of the test verbatim:\n"
        << block;
    ++blocks;
    at = stop;
  }
  EXPECT_EQ(blocks, 3);
}

// ------------------------------------------------------------ the effect itself

TEST(CustomEffect, DescribesItselfWithPhysicalParameters) {
  const auto e = MakeSealPreloadFriction();
  EXPECT_EQ(e->name(), "seal_preload_friction");
  EXPECT_EQ(e->stage(), EffectStage::kFriction);
  EXPECT_FALSE(e->description().empty());
  ExpectContains(std::string(e->signature()), "mu_seal*P");
  ASSERT_EQ(e->parameters().size(), 2u);
  const ParameterSpec& preload = e->parameters()[0];
  const ParameterSpec& mu = e->parameters()[1];
  EXPECT_EQ(preload.name, "preload_n");
  EXPECT_EQ(preload.unit, "N");
  EXPECT_EQ(preload.default_value, kDefaultPreloadN);
  EXPECT_EQ(mu.name, "mu_seal");
  EXPECT_EQ(mu.unit, "1");
  EXPECT_EQ(mu.default_value, kDefaultMuSeal);
  for (const ParameterSpec& p : e->parameters()) {
    EXPECT_FALSE(p.doc.empty()) << p.name;
    EXPECT_LT(p.lower, p.upper) << p.name;
    EXPECT_GE(p.default_value, p.lower) << p.name;
    EXPECT_LE(p.default_value, p.upper) << p.name;
    EXPECT_GE(p.lower, 0.0) << p.name;  // a preload and a friction coefficient are >= 0
  }
}

TEST(CustomEffect, HookIsCoulombsLawOfThePreloadAndOtherHooksAreNeutral) {
  const auto e = MakeSealPreloadFriction();
  for (const auto& [preload, mu] :
       std::vector<std::pair<double, double>>{{2.0, 0.15}, {0.0, 0.5}, {6.0, 0.25}, {20.0, 1.0}}) {
    const double p[] = {preload, mu};
    for (double load : {0.0, 3.0}) {
      EffectContext c;
      c.total_bend_rad = std::numbers::pi;
      c.gap_mm = 0.8;
      c.tip_load_n = load;
      for (double v : {0.0, 0.5, 15.0, 300.0}) {  // independent of speed and geometry
        EXPECT_DOUBLE_EQ(e->FrictionMagnitudeN(v, c, p), mu * preload);
      }
      EXPECT_EQ(e->FrictionScale(c, p), 1.0);
      EXPECT_EQ(e->DriveOffsetMm(1.7, c, p), 0.0);
      EXPECT_EQ(e->BacklashWidthMm(2.5, 1.3, c, p), 2.5);
      EXPECT_EQ(e->TraversalTimeConstantS(p), 0.0);
      EXPECT_EQ(e->SensorDelayS(p), 0.0);
      EXPECT_EQ(e->SensorScale(p), 1.0);
    }
  }
}

// ------------------------------------------------------- registry and SPEC grammar

TEST(CustomEffect, RegistersAfterTheBuiltinCatalog) {
  const EffectRegistry builtin = EffectRegistry::WithBuiltinEffects();
  Names expected = builtin.Names();
  expected.push_back("seal_preload_friction");
  EXPECT_EQ(Registry().Names(), expected);
  EXPECT_TRUE(Registry().Contains("seal_preload_friction"));
  EXPECT_EQ(Registry().Create("seal_preload_friction")->name(), "seal_preload_friction");
  // The copy is the user's; the built-in catalog (what the CLI uses) does not change.
  EXPECT_FALSE(EffectRegistry::WithBuiltinEffects().Contains("seal_preload_friction"));
}

TEST(CustomEffect, ModelSpecAcceptsSeedPlusTheNewEffect) {
  const Names expected = {"coulomb_friction", "viscous_friction", "backlash",
                          "seal_preload_friction"};
  EXPECT_EQ(ParseModelSpec("seed+seal_preload_friction", Registry()), expected);
  EXPECT_EQ(ParseModelSpec("seal_preload_friction+seed", Registry()), expected);
  EXPECT_EQ(FormatModelSpec(expected), "seed+seal_preload_friction");
  // Registered last, so it comes last in pipeline order.
  EXPECT_EQ(ParseModelSpec("seal_preload_friction+capstan_friction+seed", Registry()),
            (Names{"coulomb_friction", "viscous_friction", "capstan_friction", "backlash",
                   "seal_preload_friction"}));
  ExpectContains(InvalidArgumentMessage([] {
                   ParseModelSpec("seed+seal_preload_friction+seal_preload_friction", Registry());
                 }),
                 "twice");
  // The built-in registry does not know it, and says so naming the token.
  ExpectContains(InvalidArgumentMessage([] {
                   ParseModelSpec("seed+seal_preload_friction",
                                  EffectRegistry::WithBuiltinEffects());
                 }),
                 "'seal_preload_friction'");
}

TEST(CustomEffect, RegistrationRejectsDuplicatesAndMisnamedFactories) {
  EffectRegistry r = RegistryWithSeal();
  const Names before = r.Names();
  ExpectContains(
      InvalidArgumentMessage([&] { r.Register("seal_preload_friction", MakeSealPreloadFriction); }),
      "registered twice");
  ExpectContains(
      InvalidArgumentMessage([&] { r.Register("coulomb_friction", MakeCoulombFriction); }),
      "registered twice");
  // A factory whose effect reports another name than the one it is registered under.
  const std::string msg =
      InvalidArgumentMessage([&] { r.Register("o_ring_friction", MakeSealPreloadFriction); });
  ExpectContains(msg, "o_ring_friction");
  ExpectContains(msg, "another name");
  EffectRegistry empty;
  EXPECT_THROW(empty.Register("viscous_friction", MakeSealPreloadFriction), std::invalid_argument);
  EXPECT_EQ(r.Names(), before);  // failed registrations leave the registry unchanged
  EXPECT_TRUE(empty.Names().empty());
}

// ------------------------------------------------------------ TransmissionModel

TEST(CustomEffect, ModelExposesQualifiedParametersWithDefaults) {
  TransmissionModel m(Registry(), ParseModelSpec("seed+seal_preload_friction", Registry()),
                      formats::CatheterConfig::SeedEvaluation());
  ASSERT_TRUE(m.HasEffect("seal_preload_friction"));
  const std::vector<ParameterInfo>& info = m.parameter_info();
  ASSERT_EQ(info.size(), 5u);  // f0_n, mu_tip, b_n_per_mm_s, then the seal's two
  EXPECT_EQ(info[3].qualified_name, "seal_preload_friction.preload_n");
  EXPECT_EQ(info[4].qualified_name, "seal_preload_friction.mu_seal");
  EXPECT_EQ(info[3].spec.unit, "N");
  EXPECT_EQ(m.GetParameter("seal_preload_friction.preload_n"), kDefaultPreloadN);
  EXPECT_EQ(m.GetParameter("seal_preload_friction.mu_seal"), kDefaultMuSeal);

  m.SetParameter("seal_preload_friction.preload_n", 6.0);
  EXPECT_EQ(m.GetParameter("seal_preload_friction.preload_n"), 6.0);
  // Outside the physical bounds: rejected, naming the parameter, value unchanged.
  for (double bad : {-1.0, 25.0, std::nan("")}) {
    ExpectContains(
        InvalidArgumentMessage([&] { m.SetParameter("seal_preload_friction.preload_n", bad); }),
        "seal_preload_friction.preload_n");
  }
  ExpectContains(
      InvalidArgumentMessage([&] { m.SetParameter("seal_preload_friction.mu_seal", 1.5); }),
      "seal_preload_friction.mu_seal");
  EXPECT_EQ(m.GetParameter("seal_preload_friction.preload_n"), 6.0);
}

// An effect that overrides only its per-sample hook gets whole-trial hooks that agree.
TEST(CustomEffect, WholeTrialHooksFallBackToThePerSampleHook) {
  TransmissionModel m(Registry(), ParseModelSpec("seed+seal_preload_friction", Registry()),
                      formats::CatheterConfig::SeedEvaluation());
  m.SetParameter("seal_preload_friction.preload_n", 6.0);
  ExpectWholeTrialHooksMatchPerSample(m);
}

TEST(CustomEffect, AddsMuTimesPreloadToThePipelineFriction) {
  formats::CatheterConfig g = formats::CatheterConfig::SeedEvaluation();
  g.tip_load_n = 1.5;
  for (const auto& [preload, mu] : std::vector<std::pair<double, double>>{
           {kDefaultPreloadN, kDefaultMuSeal}, {6.0, 0.25}, {0.0, 0.15}}) {
    const double seal_n = mu * preload;
    TransmissionModel without(Registry(), ParseModelSpec("seed", Registry()), g);
    TransmissionModel with(Registry(), ParseModelSpec("seed+seal_preload_friction", Registry()), g);
    with.SetParameter("seal_preload_friction.preload_n", preload);
    with.SetParameter("seal_preload_friction.mu_seal", mu);
    for (double v : {0.0, 1.0, 15.0, 100.0}) {
      EXPECT_NEAR(with.FrictionMagnitudeN(v) - without.FrictionMagnitudeN(v), seal_n, 1e-12) << v;
    }
    EXPECT_NEAR(with.FrictionLevelN() - without.FrictionLevelN(), seal_n, 1e-12);
    // Every other stage is untouched (neutral defaults).
    EXPECT_EQ(with.DriveMm(3.0, 1.2), without.DriveMm(3.0, 1.2));
    EXPECT_EQ(with.BacklashWidthMm(), without.BacklashWidthMm());
    EXPECT_EQ(with.TraversalTimeConstantS(), 0.0);
    EXPECT_EQ(with.SensorDelayS(), 0.0);
    EXPECT_EQ(with.SensorScale(), 1.0);

    // Composition by the pipeline rules: the capstan factor multiplies the seal term
    // too, and friction_backlash widens the deadzone by θ·gap·b·(mu_seal·P).
    TransmissionModel capstan_without(Registry(),
                                      ParseModelSpec("seed+capstan_friction", Registry()), g);
    TransmissionModel capstan_with(
        Registry(), ParseModelSpec("seed+capstan_friction+seal_preload_friction", Registry()), g);
    capstan_with.SetParameter("seal_preload_friction.preload_n", preload);
    capstan_with.SetParameter("seal_preload_friction.mu_seal", mu);
    const double factor =
        std::exp(capstan_with.GetParameter("capstan_friction.mu") * g.TotalBendRad());
    EXPECT_NEAR(capstan_with.FrictionMagnitudeN(15.0) - capstan_without.FrictionMagnitudeN(15.0),
                factor * seal_n, 1e-12);

    const Names fb = {"coulomb_friction", "viscous_friction", "friction_backlash"};
    Names fb_seal = fb;
    fb_seal.push_back("seal_preload_friction");
    TransmissionModel fb_without(Registry(), fb, g);
    TransmissionModel fb_with(Registry(), fb_seal, g);
    fb_with.SetParameter("seal_preload_friction.preload_n", preload);
    fb_with.SetParameter("seal_preload_friction.mu_seal", mu);
    EXPECT_NEAR(
        fb_with.BacklashWidthMm() - fb_without.BacklashWidthMm(),
        g.TotalBendRad() * g.GapMm() * fb_with.GetParameter("friction_backlash.b_per_n") * seal_n,
        1e-12);
  }
}

// ------------------------------------------------------------------ closed loop

using testing::kDt;
const SensorParams kSensors{};

struct Stroke {
  std::vector<double> force;     // force sensor, N
  std::vector<double> velocity;  // true base velocity, mm/s
};

// Drives the base at constant velocity `v` (mm/s) for `duration_s` with a stiff PD on the
// true base position and velocity (kp = 10 N/mm, kd = 0.2 N/(mm/s), as in
// tests/hw/simulated_catheter_test.cc), and keeps the samples after `skip_s` (the loop
// settles in a few ms).
Stroke ConstantVelocity(PlantOptions options, double v, double duration_s, double skip_s) {
  const double start = v > 0.0 ? -20.0 : 20.0;
  SimulatedCatheter plant(std::move(options));
  plant.ResetTo(start);
  plant.Configure();
  plant.Activate();
  const std::size_t s_sensor = plant.StateIndex(iface::kSensorForce);
  const std::size_t c_force = plant.CommandIndex(iface::kActuatorForce);
  constexpr double kp = 10.0;
  constexpr double kd = 0.2;
  Stroke out;
  const auto n = static_cast<std::size_t>(std::llround(duration_s / kDt));
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * kDt;
    const PlantTruth truth = plant.truth();
    plant.read(t, kDt);
    if (t >= skip_s) {
      out.force.push_back(plant.state(s_sensor));
      out.velocity.push_back(truth.base_velocity_mm_s);
    }
    plant.set_command(c_force,
                      kp * (start + v * t - truth.base_mm) + kd * (v - truth.base_velocity_mm_s));
    plant.write(t, kDt);
  }
  return out;
}

double Mean(const std::vector<double>& x) {
  return std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(x.size());
}

double MeanTolerance(std::size_t n) {
  return 4.0 * kSensors.force_noise_n / std::sqrt(static_cast<double>(n)) +
         0.5 * kSensors.force_quantum_n;
}

double DifferenceTolerance(std::size_t n) {
  return 4.0 * kSensors.force_noise_n * std::sqrt(2.0 / static_cast<double>(n)) +
         kSensors.force_quantum_n;
}

TEST(CustomEffectInClosedLoop, RaisesTheMeanForceByMuTimesPreload) {
  const EffectRegistry& registry = Registry();
  struct Case {
    std::vector<std::pair<std::string, double>> parameters;
    double seal_n;  // mu_seal · P
  };
  const std::vector<Case> cases = {
      {{}, kDefaultMuSeal * kDefaultPreloadN},
      {{{"seal_preload_friction.preload_n", 6.0}, {"seal_preload_friction.mu_seal", 0.25}}, 1.5}};
  const double speed = 15.0;
  for (const Case& c : cases) {
    for (double sign : {1.0, -1.0}) {
      const double v = sign * speed;
      PlantOptions seal;
      seal.registry = &registry;
      seal.effects = ParseModelSpec("seed+seal_preload_friction", registry);
      seal.parameters = c.parameters;
      PlantOptions plain;
      plain.effects = ParseModelSpec("seed", registry);

      const Stroke with = ConstantVelocity(seal, v, 1.5, 0.3);
      const Stroke without = ConstantVelocity(plain, v, 1.5, 0.3);
      ASSERT_GT(with.force.size(), 1000u);
      ASSERT_EQ(with.force.size(), without.force.size());
      ASSERT_NEAR(Mean(with.velocity), v, 1e-3 * speed);
      ASSERT_NEAR(Mean(without.velocity), v, 1e-3 * speed);

      // The seed's friction by its equation (default parameters, no tip load) plus the seal.
      const double seed_n = 1.0 + 0.006 * speed;
      const std::size_t n = with.force.size();
      EXPECT_NEAR(Mean(without.force), sign * seed_n, MeanTolerance(n)) << v;
      EXPECT_NEAR(Mean(with.force), sign * (seed_n + c.seal_n), MeanTolerance(n)) << v;
      EXPECT_NEAR(Mean(with.force) - Mean(without.force), sign * c.seal_n, DifferenceTolerance(n))
          << "v " << v << " seal " << c.seal_n;
    }
  }
}

TEST(CustomEffectInClosedLoop, RaisesTheBreakawayLevel) {
  // A constant force between the seed's breakaway level (1 N) and 1 N + mu_seal·P
  // (1.3 N) moves the seed plant but leaves the plant with the valve at rest.
  const EffectRegistry& registry = Registry();
  PlantOptions seal;
  seal.registry = &registry;
  seal.effects = ParseModelSpec("seed+seal_preload_friction", registry);
  PlantOptions plain;
  auto travel = [](PlantOptions o) {
    SimulatedCatheter plant(std::move(o));
    plant.Configure();
    plant.Activate();
    const std::size_t c_force = plant.CommandIndex(iface::kActuatorForce);
    for (int k = 0; k < 200; ++k) {
      plant.read(k * kDt, kDt);
      plant.set_command(c_force, 1.15);
      plant.write(k * kDt, kDt);
    }
    return plant.truth().base_mm;
  };
  EXPECT_GT(travel(plain), 0.1);
  EXPECT_EQ(travel(seal), 0.0);
}

}  // namespace
}  // namespace echoservo::hw
