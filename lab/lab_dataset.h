// A dataset prepared for the model lab: the trials (formats/trial_io.h) with what every fit
// needs computed once — the base velocity (a centred difference over ±5 ms of the
// measured base, mm/s), the samples used as residuals (every `stride`-th), and the
// measurement noise of the tip (mm) and force (N) channels estimated from the data
// itself (robust scale of the second differences), which normalises the residuals so
// that a model that explains everything leaves a mean-square residual of about 1.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "formats/trial_io.h"

namespace echoservo::lab {

struct NoiseLevels {
  double tip_mm = 0.0;
  double force_n = 0.0;
};

struct LabTrial {
  formats::Trial trial;
  std::vector<double> velocity_mm_s;
  std::vector<double> acceleration_mm_s2;
  // True where the base comes to rest or reverses within the velocity window, and within
  // a window of the trial's first and last samples (where the centred difference is
  // one-sided): the guidewire may be stuck and the friction force is only bounded.
  std::vector<std::uint8_t> may_stick;
  std::vector<std::size_t> fit_index;  // samples that enter the fit
};

struct LabDataset {
  std::vector<LabTrial> trials;
  NoiseLevels noise;
  std::vector<std::string> skipped;  // "file: reason", with --skip-bad
  std::size_t residual_samples() const;
};

struct LabDatasetOptions {
  bool skip_bad = false;  // skip invalid trials (listed in `skipped`) instead of failing
  int stride = 4;         // use every stride-th sample as a residual (1 kHz → 250 Hz)
  double velocity_window_s = 0.01;
  double stick_speed_mm_s = 1.0;
};

// Reads every trial of `dir`. Throws formats::TrialFormatError naming the file, line and
// problem unless `skip_bad`, in which case a dataset without any valid trial throws.
LabDataset LoadLabDataset(const std::filesystem::path& dir, const LabDatasetOptions& options = {});
// Prepares trials already in memory.
LabDataset PrepareLabDataset(std::vector<formats::Trial> trials,
                             const LabDatasetOptions& options = {});

// Robust noise σ of a uniformly sampled signal: 1.4826·MAD of its second differences
// / √6, floored by the quantum (smallest non-zero step) / √12 and by `floor`.
double EstimateNoise(const std::vector<double>& signal, double floor);

// On a large dataset the lab chooses between candidate terms on a selection of trials spread
// over it (then refits what it keeps on every trial): this many.
inline constexpr std::size_t kSelectionTrials = 16;
// `count` trials spread evenly over `dataset` (trial k·n/count), with its noise levels.
LabDataset SpreadTrials(const LabDataset& dataset, std::size_t count);

}  // namespace echoservo::lab
