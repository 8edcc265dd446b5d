// Runs a catheter model (hw::TransmissionModel) along a measured trial.
//
// The model is driven by the measured base position: the friction force is the
// model's friction magnitude at the measured base speed, opposing the motion; where
// the base stops or reverses the guidewire may be stuck and static friction can take
// any value up to the breakaway level, so the prediction there is the measured force clamped to
// ±breakaway (only a force beyond breakaway is a model error; where kinetic friction at the
// estimated speed exceeds breakaway, the band is ±kinetic instead). The drive is the
// base plus the model's offsets, the tip follows the deadzone from an initial contact
// state, and the tip sensor applies the model's delay and gain plus a per-trial offset.
// Effects with signal hooks (hw/effect.h; model.UsesSignals()) see each sample's time since
// the trial's first sample, base position, velocity and acceleration (LabTrial's): their
// friction and breakaway vary per sample, their signed extra force (ForceN) is added to
// the predicted force (where the guidewire may stick, the measured force less that extra
// force is what the friction band clamps; the drive sees the friction alone), and their
// sensor offsets at the delayed tip are added to the tip reading. Without such effects
// the prediction is computed exactly as before, bit for bit.
// Per-trial nuisance: tip-sensor offset (mm) and initial contact state c ∈ [−1, 1]
// (the tip starts at drive + c·B/2). Units: mm, s, N.
#pragma once

#include <vector>

#include "hw/transmission_model.h"
#include "lab/lab_dataset.h"

namespace echoservo::lab {

struct TrialNuisance {
  double tip_offset_mm = 0.0;
  double contact = 0.0;
};

struct Prediction {
  std::vector<double> tip_mm;   // as the tip sensor would read it
  std::vector<double> force_n;  // as the force sensor would read it
};

// `model` must already hold the trial's configuration and the parameters to use.
void PredictTrial(const hw::TransmissionModel& model, const LabTrial& trial,
                  const TrialNuisance& nuisance, Prediction& out);

}  // namespace echoservo::lab
