// A tuning study's SPEC (JSON), as `echoservo tune SPEC.json --out STUDY` reads it:
//
//   {
//     "recordings": ["rec/a.igs.mha", "rec/",                  // files, or folders of them
//                    {"path": "RUN1", "em": "RUN1/em.csv"}],   // a RUN with its EM log
//     "scoring": {"metric": "loop.tip_to_target_rms_mm",      // tune/trial.h metric names
//                 "latency_s": 0.1, "delay_s": 0.1, "from_s": 3.0},
//     "parameters": {                                           // live/pipeline_parameters.h
//       "detector.sheath_diameter_mm": {"values": [1.5, 2.5, 3.5]},   // grid values
//       "predictor.init_window_s": {"min": 1.0, "max": 4.0, "steps": 4}  // or a range
//     },
//     "fixed": {"predictor.harmonics": 4},                      // applied to every set
//     "search": {"method": "grid" | "random" | "adaptive", "trials": 20, "seed": 1},
//     "timeout_s": 600, "jobs": 2
//   }
// Relative paths are relative to the SPEC's folder. A "range" without "steps" is continuous
// (random and adaptive search; grid needs steps or values). Every name, value and bound is
// checked against the registry before anything runs; every recording is inspected
// (tune/trial.h InspectRecording) and the metric checked against what it has.
// Errors: std::invalid_argument naming the SPEC item and why (unknown parameter with the
// closest names, value outside its bounds, recording missing or unreadable, a metric that
// needs truth or an EM log the recording lacks, an unknown search method).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "live/pipeline_parameters.h"
#include "tune/trial.h"

namespace echoservo::tune {

struct ParameterAxis {
  std::string name;
  std::vector<double> values;   // grid values (explicit, or min..max in steps)
  double min = 0.0, max = 0.0;  // the range searched (random, adaptive)
};

struct RecordingSpec {
  std::string path;    // absolute
  std::string em_log;  // absolute; empty: none / RUN's em.csv
  std::string name;    // short, unique
  RecordingInfo info;
};

struct StudySpec {
  std::vector<RecordingSpec> recordings;
  std::string metric;
  bool minimize = true;
  double latency_s = 0.1, delay_s = -1.0, from_s = 3.0;
  bool loop = true;  // false when the metric needs no re-simulated loop
  std::vector<ParameterAxis> axes;
  std::vector<live::Assignment> fixed;
  std::string method = "grid";
  int trials = 0;  // random/adaptive: parameter sets to evaluate (the default not counted)
  std::uint64_t seed = 1;
  double timeout_s = 600.0;
  int jobs = 0;
  std::string normalised_json;
  std::string path;  // where the SPEC was read from (ParseStudySpec's `path`)
};

// Throws std::invalid_argument naming `path` and the item.
StudySpec ParseStudySpec(std::string_view json, const std::string& path);
StudySpec ReadStudySpec(const std::string& path);

}  // namespace echoservo::tune
