// The seed's tip-tracking experiment (Kesner & Howe 2010, §V): the base servo makes
// the tip follow a reference (1 Hz sine or mitral annulus motion) with a chosen
// backlash compensation, and the tip error is reported (MAE, RMS, max in mm) over
// the window after `metrics_start_s`. The iterative (offline) compensation repeats
// the whole run `iterations` times, learning between runs; the reported figures are
// those of the last run. All other methods get a single run.
#pragma once

#include <string>
#include <vector>

#include "control/experiments/error_stats.h"
#include "control/servo_loop.h"
#include "hw/simulated_catheter.h"

namespace echoservo::control {

struct TrackOptions {
  std::string trajectory = "sine";    // a trajectory spec (control/trajectory.h)
  std::string compensation = "none";  // none | inverse | iterative | adaptive
  double duration_s = 12.0;
  double metrics_start_s = 2.0;
  int iterations = 1;      // iterative: learning runs before the reported one
  hw::PlantOptions plant;  // defaults to the seed-calibrated plant
  ServoConfig servo;
  bool friction_feedforward = true;
  // Throws std::invalid_argument naming the field.
  void Validate() const;
  static TrackOptions SeedDefaults();
};

struct TrackResult {
  ErrorStats tip;                   // of the reported run
  std::vector<ErrorStats> per_run;  // iterative: one per run (run 0 uncompensated)
  double width_estimate_mm = 0.0;   // inverse/adaptive: the width used at the end
  double lag_estimate_s = 0.0;      // adaptive
  std::uint64_t limit_faults = 0;
  std::vector<CycleRecord> records;  // the reported run
};

TrackResult RunTrackExperiment(const TrackOptions& options);

// The servo configuration used for the seed experiments (gains tuned for the
// simulated voice coil; friction feed-forward from the plant's nominal friction).
ServoConfig SeedServoConfig(const hw::PlantOptions& plant, bool friction_feedforward);

}  // namespace echoservo::control
