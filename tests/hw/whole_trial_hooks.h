// Checks that a model's whole-trial hooks (TransmissionModel::FrictionMagnitudesN and
// DrivesMm) give, bit for bit, what its per-sample calls give: over speeds from rest to
// beyond the mitral annulus's 210 mm/s and forces of either sign.
#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <vector>

#include "hw/transmission_model.h"

namespace echoservo::hw {

inline void ExpectWholeTrialHooksMatchPerSample(const TransmissionModel& m) {
  const std::vector<double> speed_mm_s = {0.0, 0.5, 1.0, 3.0, 20.0, 100.0, 250.0};
  const std::vector<double> base_mm = {-4.0, -1.0, 0.0, 0.25, 1.0, 7.5, 12.0};
  const std::vector<double> force_n = {-3.0, -1.2, -0.01, 0.0, 0.4, 1.2, 4.0};
  std::vector<double> friction(speed_mm_s.size()), drive(base_mm.size());
  m.FrictionMagnitudesN(speed_mm_s, friction);
  m.DrivesMm(base_mm, force_n, drive);
  for (std::size_t i = 0; i < speed_mm_s.size(); ++i) {
    EXPECT_EQ(friction[i], m.FrictionMagnitudeN(speed_mm_s[i])) << speed_mm_s[i] << " mm/s";
    EXPECT_EQ(drive[i], m.DriveMm(base_mm[i], force_n[i])) << force_n[i] << " N";
  }
}

}  // namespace echoservo::hw
