// Compiled effect plugins (hw/effect_plugin.h): the example plugin's quadratic_drag
// (F = c·v², hw/plugins/example_effect_plugin.cc) through the registry, the model, the
// prediction, a fit and the simulated catheter; refusals of a wrong ABI, a library that is
// not a plugin and a missing file.
//
// The fit recovers c from noise-free trials predicted with a known c: the model is exact,
// so Levenberg–Marquardt must land on it to 1e-6 relative.
#include "hw/effect_plugin.h"

#include <dlfcn.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "hw/effect_file.h"
#include "hw/simulated_catheter.h"
#include "hw/transmission_model.h"
#include "lab/lab_dataset.h"
#include "lab/model_fit.h"
#include "lab/model_prediction.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::hw {
namespace {

using ::echoservo::testing::ExpectContains;
using ::echoservo::testing::InvalidArgumentMessage;

const EffectRegistry& WithPlugin() {
  static const EffectRegistry r = [] {
    EffectRegistry reg = EffectRegistry::WithBuiltinEffects();
    LoadEffectPlugin(ECHOSERVO_EXAMPLE_EFFECT_PLUGIN, reg);
    return reg;
  }();
  return r;
}

TEST(EffectPlugin, RegistersItsEffectAfterTheBuiltins) {
  const EffectRegistry& r = WithPlugin();
  ASSERT_TRUE(r.Contains("quadratic_drag"));
  EXPECT_EQ(r.Names().back(), "quadratic_drag");
  EXPECT_EQ(r.Source("quadratic_drag"), "");
  TransmissionModel m(r, ParseModelSpec("seed+quadratic_drag", r),
                      formats::CatheterConfig::SeedEvaluation());
  TransmissionModel seed(r, SeedEffects(), formats::CatheterConfig::SeedEvaluation());
  EXPECT_NEAR(m.FrictionMagnitudeN(20.0) - seed.FrictionMagnitudeN(20.0), 1e-5 * 400.0, 1e-15);
  EXPECT_EQ(m.FrictionLevelN(), seed.FrictionLevelN());
}

lab::LabDataset DragDataset(double c) {
  std::vector<formats::Trial> trials;
  for (const double amplitude : {3.0, 6.0}) {
    formats::Trial t;
    t.name = "sine" + std::to_string(static_cast<int>(amplitude));
    t.config = formats::CatheterConfig::SeedEvaluation();
    for (int i = 0; i < 1500; ++i) {
      const double ts = 1e-3 * i;
      const double x = amplitude * std::sin(2.0 * std::numbers::pi * 1.5 * ts);
      t.t_s.push_back(ts);
      t.base_cmd_mm.push_back(x);
      t.base_mm.push_back(x);
      t.tip_mm.push_back(x);
      t.force_n.push_back(0.0);
    }
    trials.push_back(std::move(t));
  }
  lab::LabDataset ds = lab::PrepareLabDataset(std::move(trials));
  // The measured channels are the exact model prediction with drag c.
  TransmissionModel m(WithPlugin(), {"coulomb_friction", "quadratic_drag"},
                      formats::CatheterConfig::SeedEvaluation());
  m.SetParameter("quadratic_drag.c_n_per_mm2_s2", c);
  for (lab::LabTrial& lt : ds.trials) {
    lab::Prediction p;
    lab::PredictTrial(m, lt, {}, p);
    lt.trial.force_n = p.force_n;
    lt.trial.tip_mm = p.tip_mm;
  }
  ds.noise = {0.01, 0.01};
  return ds;
}

TEST(EffectPlugin, FitsItsParameter) {
  const double c = 4e-5;
  const lab::LabDataset ds = DragDataset(c);
  lab::FitOptions o;
  o.registry = &WithPlugin();
  o.threads = 2;
  const lab::FitResult r = lab::FitModel({"coulomb_friction", "quadratic_drag"}, ds, o);
  ASSERT_FALSE(r.estimates.empty());
  EXPECT_EQ(r.estimates.back().name, "quadratic_drag.c_n_per_mm2_s2");
  EXPECT_NEAR(r.estimates.back().value, c, 1e-6 * c);
}

TEST(EffectPlugin, SimulatesInTheCatheter) {
  PlantOptions o;
  o.registry = &WithPlugin();
  o.effects = ParseModelSpec("seed+quadratic_drag", WithPlugin());
  o.sensor_noise = false;
  SimulatedCatheter plant(o);
  plant.Configure();
  plant.Activate();
  for (int i = 0; i < 200; ++i) {
    plant.read(1e-3 * i, 1e-3);
    plant.set_command(0, 4.0 * std::sin(2.0 * std::numbers::pi * 3.0 * 1e-3 * i));
    plant.write(1e-3 * i, 1e-3);
  }
  EXPECT_GT(std::abs(plant.truth().base_mm), 0.1);
}

TEST(EffectPlugin, FileEffectCannotTakeAPluginName) {
  EffectRegistry r = EffectRegistry::WithBuiltinEffects();
  LoadEffectPlugin(ECHOSERVO_EXAMPLE_EFFECT_PLUGIN, r);
  const auto path = std::filesystem::temp_directory_path() /
                    ("echoservo_plugin_clash_" + std::to_string(::getpid()) + ".json");
  EffectFileSpec s;
  s.name = "quadratic_drag";
  s.parameters = {{"c", "N", 0.1, 0.0, 1.0, ""}};
  s.expressions = {{"friction_n", "c"}};
  WriteEffectFile(path, s);
  const std::string m =
      InvalidArgumentMessage([&] { ResolveModelSpec("seed+@" + path.string(), r); });
  std::filesystem::remove(path);
  ExpectContains(m, path.string());
  ExpectContains(m, "quadratic_drag");
  ExpectContains(m, "plugin");
  // Loading the same plugin twice registers its name twice.
  ExpectContains(
      InvalidArgumentMessage([&] { LoadEffectPlugin(ECHOSERVO_EXAMPLE_EFFECT_PLUGIN, r); }),
      "registered twice");
}

TEST(EffectPlugin, RefusesAWrongAbiNamingBothNumbers) {
  EffectRegistry r = EffectRegistry::WithBuiltinEffects();
  const std::string m =
      InvalidArgumentMessage([&] { LoadEffectPlugin(ECHOSERVO_WRONG_ABI_EFFECT_PLUGIN, r); });
  ExpectContains(m, ECHOSERVO_WRONG_ABI_EFFECT_PLUGIN);
  ExpectContains(m, "ABI " + std::to_string(kEffectPluginAbi + 1));
  ExpectContains(m, "expects ABI " + std::to_string(kEffectPluginAbi));
  EXPECT_EQ(r.Names(), EffectRegistry::WithBuiltinEffects().Names());
}

TEST(EffectPlugin, RefusesAMissingFileAndALibraryWithoutTheEntryPoints) {
  EffectRegistry r = EffectRegistry::WithBuiltinEffects();
  const std::string missing = "/nonexistent/echoservo_plugin.so";
  const std::string m = InvalidArgumentMessage([&] { LoadEffectPlugin(missing, r); });
  ExpectContains(m, missing);
  ExpectContains(m, "cannot load");
  // A real shared library that is not a plugin: the C library's math, found from cos.
  Dl_info info{};
  double (*cos_fn)(double) = &std::cos;
  ASSERT_NE(::dladdr(reinterpret_cast<void*>(cos_fn), &info), 0);
  const std::string libm = info.dli_fname;
  const std::string n = InvalidArgumentMessage([&] { LoadEffectPlugin(libm, r); });
  ExpectContains(n, libm);
  ExpectContains(n, "does not export echoservo_effect_plugin_abi");
}

}  // namespace
}  // namespace echoservo::hw
