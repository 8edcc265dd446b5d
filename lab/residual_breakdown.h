// Where a model fails: its residuals broken down by phase of motion, base speed,
// configuration (gap, total bend angle, tip load) and trial.
//
// Phases come from the measured base alone: "after_reversal" (within 80 ms after the
// base velocity changed sign, ignoring wiggles below 1 mm/s), "rest" (|v| < 1 mm/s),
// "acceleration" (|a| above a quarter of the dataset's 95th-percentile |a|) and
// "constant_velocity" (the rest). For every group: samples, tip RMS (mm), force RMS (N),
// and the group's share of samples and of each channel's squared residual (a share of
// squared error well above the share of samples says the misfit concentrates there).
#pragma once

#include <string>
#include <vector>

#include "lab/model_fit.h"

namespace echoservo::lab {

struct GroupStat {
  std::string label;
  std::size_t samples = 0;
  double tip_rms_mm = 0.0;
  double force_rms_n = 0.0;
  double sample_share = 0.0;
  double tip_share = 0.0;
  double force_share = 0.0;
  double value = 0.0;  // numeric key (speed bin start, gap, angle, load); 0 for phases
};

struct Breakdown {
  std::vector<GroupStat> phase;
  std::vector<GroupStat> speed;
  std::vector<GroupStat> gap;
  std::vector<GroupStat> bend;
  std::vector<GroupStat> tip_load;
  std::vector<GroupStat> trial;
};

// `fit` must hold one TrialResult per trial of `dataset`, in order.
Breakdown ComputeBreakdown(const LabDataset& dataset, const FitResult& fit);

// Phase label of every sample of a trial (exposed for tests and reports).
std::vector<std::string> ClassifyPhases(const LabTrial& trial, double acceleration_threshold_mm_s2);
double AccelerationThreshold(const LabDataset& dataset);

}  // namespace echoservo::lab
