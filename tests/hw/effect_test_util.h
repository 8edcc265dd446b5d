// Trials and plant runs shared by the effect-file tests (effect files, tabulated terms,
// signal backlash): one lab trial along a measured sine and a short simulated-catheter run.
// Units: mm, s, N.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include "hw/effect_registry.h"
#include "hw/simulated_catheter.h"
#include "lab/lab_dataset.h"

namespace echoservo::hw::testing {

// A fixture with a scratch folder of its own per test (removed afterwards) and a writer of
// effect files into it.
class ScratchFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("echoservo_hw_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->test_suite_name() + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  // Writes `text` to `file` in the scratch folder; its path.
  std::string Write(const std::string& file, const std::string& text) {
    const auto path = dir_ / file;
    std::ofstream(path) << text;
    return path.string();
  }
  std::filesystem::path dir_;
};

// A 2 s, 1 kHz trial of a ±4 mm 0.8 Hz sine starting at t = 0.5 s (so that time_s = t − t0
// differs from t), with a square-wave force and the tip following the base.
inline lab::LabTrial SineTrial() {
  formats::Trial t;
  t.name = "sine";
  t.config = formats::CatheterConfig::SeedEvaluation();
  for (int i = 0; i < 2000; ++i) {
    const double ts = 0.5 + 1e-3 * i;
    const double w = 2.0 * std::numbers::pi * 0.8;
    t.t_s.push_back(ts);
    t.base_cmd_mm.push_back(4.0 * std::sin(w * ts));
    t.base_mm.push_back(4.0 * std::sin(w * ts));
    t.tip_mm.push_back(4.0 * std::sin(w * ts));
    t.force_n.push_back(std::cos(w * ts) > 0 ? 0.4 : -0.4);
  }
  return lab::PrepareLabDataset({t}).trials.front();
}

// 0.4 s of the simulated catheter with `effects` (from `r`) following a ±3 mm, 3 Hz sine
// command at 1 kHz: tip, force sensor and base position at every cycle.
inline std::vector<std::array<double, 3>> RunPlantSine(const EffectRegistry& r,
                                                       const std::vector<std::string>& effects,
                                                       bool noise) {
  PlantOptions o;
  o.effects = effects;
  o.registry = &r;
  o.sensor_noise = noise;
  SimulatedCatheter plant(o);
  plant.Configure();
  plant.Activate();
  std::vector<std::array<double, 3>> out;
  for (int i = 0; i < 400; ++i) {
    const double t = 1e-3 * i;
    plant.read(t, 1e-3);
    out.push_back({plant.state(iface::kTipPosition), plant.state(iface::kSensorForce),
                   plant.state(iface::kBasePosition)});
    plant.set_command(0, 3.0 * std::sin(2.0 * std::numbers::pi * 3.0 * t));
    plant.write(t, 1e-3);
  }
  return out;
}

}  // namespace echoservo::hw::testing
