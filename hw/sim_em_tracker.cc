#include "hw/sim_em_tracker.h"

#include <cmath>
#include <stdexcept>

namespace echoservo::hw {

void SimEmTrackerOptions::Validate() const {
  auto bad = [](const std::string& f, const std::string& why) {
    throw std::invalid_argument("SimEmTrackerOptions: " + f + " " + why);
  };
  if (!(rate_hz > 0 && rate_hz <= 1000)) bad("rate_hz", "must be in (0, 1000] Hz");
  if (!(noise_rms_mm >= 0 && noise_rms_mm <= 10)) bad("noise_rms_mm", "must be in [0, 10] mm");
  if (!(std::abs(clock_offset_s) <= 10)) bad("clock_offset_s", "must be within ±10 s");
  if (!(jitter_s >= 0 && jitter_s <= 0.5 / rate_hz))
    bad("jitter_s", "must be in [0, 0.5/rate_hz] s");
  if (!(dropout_probability >= 0 && dropout_probability <= 0.5))
    bad("dropout_probability", "must be in [0, 0.5]");
  const Eigen::Matrix3d r = image_to_em.linear();
  if (!(image_to_em.matrix().allFinite() &&
        (r * r.transpose() - Eigen::Matrix3d::Identity()).norm() < 1e-6 && r.determinant() > 0))
    bad("image_to_em", "must be a finite rigid transform");
}

SimEmTracker::SimEmTracker(SimEmTrackerOptions options, double start_s)
    : o_(std::move(options)), next_s_(start_s), start_s_(start_s), rng_(o_.seed) {
  o_.Validate();
}

formats::EmSample SimEmTracker::Sample(const Eigen::Vector3d& tip_image_mm) {
  formats::EmSample r;
  r.t_s = next_s_ + o_.clock_offset_s;
  ++samples_;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  if (u(rng_) < o_.dropout_probability) {
    ++dropouts_;
  } else {
    std::normal_distribution<double> n(0.0, o_.noise_rms_mm / std::sqrt(3.0));
    r.position_mm = o_.image_to_em * tip_image_mm + Eigen::Vector3d(n(rng_), n(rng_), n(rng_));
    r.valid = true;
  }
  ++k_;
  std::uniform_real_distribution<double> j(-o_.jitter_s, o_.jitter_s);
  next_s_ = start_s_ + static_cast<double>(k_) / o_.rate_hz + (o_.jitter_s > 0 ? j(rng_) : 0.0);
  return r;
}

}  // namespace echoservo::hw
