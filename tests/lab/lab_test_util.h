// Datasets for the model-lab tests, recorded in-process with the simulated catheter
// (control::RecordDataset) into a unique temporary folder that is removed afterwards.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "control/experiments/record_experiment.h"
#include "hw/effect_registry.h"
#include "lab/lab_dataset.h"

namespace echoservo::lab::testing {

struct Recording {
  std::string effects = "seed";                            // model SPEC of the simulated plant
  std::vector<std::pair<std::string, double>> parameters;  // overrides
  std::string configs = "lab";
  std::vector<std::string> trajectories = {"sine:4:0.8", "mitral"};
  std::vector<double> tip_loads_n = {0.0};
  double duration_s = 3.0;
  std::uint64_t seed = 1;
};

// A folder under the system temp dir, unique to this process and call, removed on exit.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& tag) {
    static std::atomic<int> counter{0};
    path_ = std::filesystem::temp_directory_path() /
            ("echoservo_lab_" + tag + "_" + std::to_string(::getpid()) + "_" +
             std::to_string(counter++));
    std::filesystem::remove_all(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// Records the dataset and loads it as the lab would from disk.
inline LabDataset Record(const Recording& r) {
  ScratchDir dir("record");
  control::RecordOptions o;
  o.out_dir = dir.path();
  o.effects = hw::ParseModelSpec(r.effects, hw::EffectRegistry::WithBuiltinEffects());
  o.parameters = r.parameters;
  o.configs = r.configs;
  o.trajectories = r.trajectories;
  o.tip_loads_n = r.tip_loads_n;
  o.duration_s = r.duration_s;
  o.seed = r.seed;
  control::RecordDataset(o);
  return LoadLabDataset(dir.path());
}

// Records `r` whose SPEC may name effect files (@path): they are registered in `registry`,
// which the simulated catheter uses while recording (installed as the default registry and
// restored afterwards, as the CLI installs its catalog).
inline LabDataset RecordResolved(const Recording& r, hw::EffectRegistry& registry) {
  ScratchDir dir("record_resolved");
  control::RecordOptions o;
  o.out_dir = dir.path();
  o.effects = hw::ResolveModelSpec(r.effects, registry);
  o.parameters = r.parameters;
  o.configs = r.configs;
  o.trajectories = r.trajectories;
  o.tip_loads_n = r.tip_loads_n;
  o.duration_s = r.duration_s;
  o.seed = r.seed;
  const hw::EffectRegistry& previous = hw::DefaultEffectRegistry();
  hw::SetDefaultEffectRegistry(&registry);
  struct Restore {
    const hw::EffectRegistry* previous;
    ~Restore() { hw::SetDefaultEffectRegistry(previous); }
  } restore{&previous};
  control::RecordDataset(o);
  return LoadLabDataset(dir.path());
}

// The generating parameters the recorder writes into every trial's meta JSON. Only tests
// read them; the model lab never does.
inline std::map<std::string, double> TruthParameters(const LabDataset& ds) {
  std::map<std::string, double> truth;
  const nlohmann::json meta = nlohmann::json::parse(ds.trials.front().trial.meta_json);
  for (const auto& [name, value] : meta.at("truth_parameters").items())
    truth[name] = value.get<double>();
  return truth;
}

}  // namespace echoservo::lab::testing
