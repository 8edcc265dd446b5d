// `sim record`: runs the simulated catheter through chosen configurations,
// trajectories and tip loads, with chosen effects, and writes a dataset in the trial
// format (formats/trial_io.h, docs/trial_format.md): one CSV + JSON pair per run.
//
// The base follows the trajectory through the servo (no compensation unless asked),
// so base_cmd is the shaped setpoint, base the encoder, tip the tip sensor and force
// the force sensor, sampled at 1 kHz. The generating effects and parameters are
// written into each trial's "meta" object for provenance; the model lab never reads it.
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "formats/catheter_config.h"

namespace echoservo::control {

struct RecordOptions {
  std::filesystem::path out_dir;
  std::vector<std::string> effects;  // empty: the seed-calibrated plant's effects
  std::vector<std::pair<std::string, double>> parameters;
  std::string configs = "table1";  // table1 (24 configurations) | seed (the tracking catheter)
  std::vector<std::string> trajectories = {"sine"};
  std::vector<double> tip_loads_n = {0.0};
  std::string compensation = "none";  // none | inverse | adaptive
  double duration_s = 6.0;
  std::uint64_t seed = 1;
  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

struct RecordResult {
  std::vector<std::string> trials;
  std::size_t samples = 0;
};

RecordResult RecordDataset(const RecordOptions& options);

std::vector<formats::CatheterConfig> RecordConfigs(const std::string& name, double tip_load_n);

}  // namespace echoservo::control
