// A simulated electromagnetic tracker on the catheter tip (as the seed's trakSTAR sensor):
// it samples the true tip position at its own rate, in its own frame and on its own clock,
// with isotropic Gaussian noise and occasional drop-outs — what an accuracy report must
// undo (time offset, EM→image registration) and reject (drop-outs).
//
// Sample k is taken at pipeline time t_k = start_s + k / rate_hz (+ uniform jitter of
// `jitter_s`); it is stamped t_em = t_k + clock_offset_s and reports
// image_to_em · p_image(t_k) + noise, or a drop-out (status MISSING, no position) with
// probability `dropout_probability`. Units: mm, s; positions in the EM tracker's frame.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <random>

#include "formats/em_log.h"

namespace echoservo::hw {

struct SimEmTrackerOptions {
  double rate_hz = 40.0;              // (0, 1000]
  double noise_rms_mm = 0.3;          // per-axis σ = rms / √3, [0, 10]
  double clock_offset_s = 0.0375;     // EM clock minus pipeline clock, |·| ≤ 10 s
  double jitter_s = 0.0;              // sampling jitter, [0, 0.5 / rate_hz]
  double dropout_probability = 0.01;  // [0, 0.5]
  Eigen::Isometry3d image_to_em = Eigen::Isometry3d::Identity();  // rigid
  std::uint64_t seed = 7;
  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

class SimEmTracker {
 public:
  // Throws std::invalid_argument for bad options.
  explicit SimEmTracker(SimEmTrackerOptions options, double start_s = 0.0);
  // Pipeline time of the next sample.
  double next_sample_s() const { return next_s_; }
  // Takes the sample due at next_sample_s() of the true tip `tip_image_mm` (image frame,
  // at that time) and schedules the next one: t_s on the EM clock, position in the EM
  // frame (zero for a drop-out). Its log rows: formats/em_log.h SimEmLogRow.
  formats::EmSample Sample(const Eigen::Vector3d& tip_image_mm);
  std::uint64_t samples() const { return samples_; }
  std::uint64_t dropouts() const { return dropouts_; }
  const SimEmTrackerOptions& options() const { return o_; }

 private:
  SimEmTrackerOptions o_;
  double next_s_;
  std::uint64_t k_ = 0;
  double start_s_;
  std::mt19937_64 rng_;
  std::uint64_t samples_ = 0, dropouts_ = 0;
};

}  // namespace echoservo::hw
