#include "lab/lab_dataset.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace echoservo::lab {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Centred difference over ±window/2, shrinking at the ends. The half window has a
// relative slack of 1e-9 so that rounding in the time stamps (0.068 − 0.063 >
// 0.005 in doubles) cannot drop a sample from one side only, which would turn the
// centred difference into a biased one-sided one.
std::vector<double> Derivative(const std::vector<double>& t, const std::vector<double>& x,
                               double window_s) {
  const std::size_t n = x.size();
  std::vector<double> d(n, 0.0);
  std::size_t lo = 0;
  std::size_t hi = 0;
  const double half = 0.5 * window_s * (1.0 + 1e-9);
  for (std::size_t i = 0; i < n; ++i) {
    while (t[i] - t[lo] > half) ++lo;
    while (hi + 1 < n && t[hi + 1] - t[i] <= half) ++hi;
    const double dt = t[hi] - t[lo];
    d[i] = dt > 0.0 ? (x[hi] - x[lo]) / dt : 0.0;
  }
  return d;
}

LabTrial Prepare(formats::Trial trial, const LabDatasetOptions& o) {
  LabTrial lt;
  lt.velocity_mm_s = Derivative(trial.t_s, trial.base_mm, o.velocity_window_s);
  lt.acceleration_mm_s2 = Derivative(trial.t_s, lt.velocity_mm_s, o.velocity_window_s);
  for (std::size_t i = 0; i < trial.size(); i += static_cast<std::size_t>(o.stride))
    lt.fit_index.push_back(i);
  // A sample may be stuck if, within ±window/2, the velocity is below the stick speed
  // or changes sign (the centred difference smears a brief stop over the window). Where
  // the window is cut by the trial's start or end the difference is one-sided and cannot
  // see a stop (a trial that starts from rest reads the speed of the motion after it),
  // so those samples count as slow too.
  const std::size_t n = trial.size();
  std::vector<std::uint8_t> slow(n);
  for (std::size_t i = 0; i < n; ++i) {
    const bool truncated = trial.t_s[i] - trial.t_s[0] < 0.5 * o.velocity_window_s ||
                           trial.t_s[n - 1] - trial.t_s[i] < 0.5 * o.velocity_window_s;
    slow[i] = truncated || std::abs(lt.velocity_mm_s[i]) < o.stick_speed_mm_s ||
              (i > 0 && lt.velocity_mm_s[i] * lt.velocity_mm_s[i - 1] < 0.0);
  }
  lt.may_stick.assign(n, 0);
  std::size_t lo = 0;
  std::size_t hi = 0;
  std::size_t count = 0;  // slow samples in [lo, hi)
  for (std::size_t i = 0; i < n; ++i) {
    while (hi < n && trial.t_s[hi] - trial.t_s[i] <= 0.5 * o.velocity_window_s) count += slow[hi++];
    while (trial.t_s[i] - trial.t_s[lo] > 0.5 * o.velocity_window_s) count -= slow[lo++];
    lt.may_stick[i] = count > 0;
  }
  lt.trial = std::move(trial);
  return lt;
}

}  // namespace

std::size_t LabDataset::residual_samples() const {
  std::size_t n = 0;
  for (const LabTrial& t : trials) n += t.fit_index.size();
  return n;
}

LabDataset SpreadTrials(const LabDataset& ds, std::size_t count) {
  LabDataset out;
  out.noise = ds.noise;
  const std::size_t n = ds.trials.size();
  for (std::size_t k = 0; k < std::min(count, n); ++k)
    out.trials.push_back(ds.trials[k * n / std::min(count, n)]);
  return out;
}

double EstimateNoise(const std::vector<double>& x, double floor) {
  if (x.size() < 3) return floor;
  std::vector<double> d2;
  d2.reserve(x.size() - 2);
  double quantum = INFINITY;
  for (std::size_t i = 2; i < x.size(); ++i) {
    d2.push_back(x[i] - 2.0 * x[i - 1] + x[i - 2]);
    const double step = std::abs(x[i] - x[i - 1]);
    if (step > 0.0) quantum = std::min(quantum, step);
  }
  const double med = Median(d2);
  for (double& v : d2) v = std::abs(v - med);
  const double sigma = 1.4826 * Median(d2) / std::sqrt(6.0);
  const double q = std::isfinite(quantum) ? quantum / std::sqrt(12.0) : 0.0;
  return std::max({sigma, q, floor});
}

LabDataset PrepareLabDataset(std::vector<formats::Trial> trials, const LabDatasetOptions& o) {
  if (o.stride < 1 || o.stride > 100)
    throw std::invalid_argument("lab: stride must be in [1, 100]");
  if (!(o.velocity_window_s > 0.0 && o.velocity_window_s < 1.0)) {
    throw std::invalid_argument("lab: velocity window must be in (0, 1) s");
  }
  if (trials.empty()) throw std::invalid_argument("lab: the dataset has no trials");
  LabDataset ds;
  std::vector<double> tip_sigmas;
  std::vector<double> force_sigmas;
  for (formats::Trial& t : trials) {
    tip_sigmas.push_back(EstimateNoise(t.tip_mm, 1e-4));
    force_sigmas.push_back(EstimateNoise(t.force_n, 1e-4));
    ds.trials.push_back(Prepare(std::move(t), o));
  }
  // One noise level per channel for the whole dataset (the same sensors throughout).
  ds.noise.tip_mm = Median(tip_sigmas);
  ds.noise.force_n = Median(force_sigmas);
  return ds;
}

LabDataset LoadLabDataset(const std::filesystem::path& dir, const LabDatasetOptions& o) {
  if (!o.skip_bad) return PrepareLabDataset(formats::ReadDataset(dir), o);
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw formats::TrialFormatError(dir.string() + ": dataset folder not found");
  }
  std::vector<std::filesystem::path> csvs;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() == ".csv") csvs.push_back(entry.path());
  }
  std::sort(csvs.begin(), csvs.end());
  std::vector<formats::Trial> trials;
  std::vector<std::string> skipped;
  for (const auto& csv : csvs) {
    try {
      trials.push_back(formats::ReadTrial(csv));
    } catch (const formats::TrialFormatError& e) {
      skipped.push_back(e.what());
    }
  }
  if (trials.empty()) {
    throw formats::TrialFormatError(dir.string() + ": no valid trial (" +
                                    std::to_string(skipped.size()) + " skipped)");
  }
  LabDataset ds = PrepareLabDataset(std::move(trials), o);
  ds.skipped = std::move(skipped);
  return ds;
}

}  // namespace echoservo::lab
