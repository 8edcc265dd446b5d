#include "control/friction_feedforward.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace echoservo::control {

void FrictionFeedforward::Validate() const {
  auto check = [](double v, const char* name) {
    if (!(std::isfinite(v) && v >= 0.0)) {
      throw std::invalid_argument(std::string("friction feed-forward: '") + name +
                                  "' must be finite and >= 0");
    }
  };
  params::kCoulombFfN.Check(coulomb_n, "friction feed-forward");
  params::kViscousFfNPerMmS.Check(viscous_n_per_mm_s, "friction feed-forward");
  check(moving_mass_kg, "moving_mass_kg");
  if (!(std::isfinite(sign_smoothing_mm_s) && sign_smoothing_mm_s > 0.0)) {
    throw std::invalid_argument("friction feed-forward: 'sign_smoothing_mm_s' must be > 0");
  }
}

double FrictionFeedforward::ForceN(double velocity_mm_s, double acceleration_mm_s2) const {
  return coulomb_n * std::tanh(velocity_mm_s / sign_smoothing_mm_s) +
         viscous_n_per_mm_s * velocity_mm_s + moving_mass_kg * acceleration_mm_s2 * 1e-3;
}

}  // namespace echoservo::control
