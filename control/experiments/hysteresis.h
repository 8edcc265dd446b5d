// Backlash (hysteresis) width from a recording of base and tip positions.
//
// Works from the data alone: velocities are taken as centred differences over a
// window, a sample is "engaged" when the base moves faster than a fraction of its
// peak speed and the tip moves with it (same direction, at least half the speed), and
// the width is mean(base − tip | engaged moving up) − mean(base − tip | engaged
// moving down): the horizontal width of the tip-vs-base loop, in mm. Axial compliance
// and lags widen it exactly as they widen a measured loop.
#pragma once

#include <cstddef>
#include <vector>

namespace echoservo::control {

struct HysteresisWidth {
  double width_mm = 0.0;
  std::size_t up_samples = 0;
  std::size_t down_samples = 0;
};

// t in s (strictly increasing), base and tip in mm, same length. Throws
// std::invalid_argument when the inputs are inconsistent or when either direction has
// no engaged sample (the motion never moved the tip both ways).
HysteresisWidth EstimateHysteresisWidth(const std::vector<double>& t_s,
                                        const std::vector<double>& base_mm,
                                        const std::vector<double>& tip_mm, double window_s = 0.02);

}  // namespace echoservo::control
