// The simulated catheter the live servo drives by default: the seed's water-tank catheter
// (hw::SeedTrackingCatheter, two bends) with a chosen sheath and guidewire, its seed-
// calibrated plant (hw::SeedCalibratedPlant), configured and active at base 0, the seed's
// servo gains with friction feed-forward, and the static backlash inverse for its
// deadzone width B = θ·(D_sheath − D_guidewire), read 6 ms ahead for the tip's lag. The adaptive
// inverse learned poorly from a reference that changes with every volume (servo tracking 1.2 mm RMS
// against 0.19 mm). Units: mm, s, N.
#pragma once

#include <cstdint>
#include <memory>

#include "control/backlash_compensation.h"
#include "control/servo_loop.h"
#include "hw/simulated_catheter.h"

namespace echoservo::live {

struct SimCatheter {
  hw::PlantOptions plant_options;
  std::unique_ptr<hw::SimulatedCatheter> plant;
  control::ServoConfig servo;
  std::unique_ptr<control::BacklashCompensator> compensator;
};

// Throws std::invalid_argument unless 0 < guidewire_od_mm < sheath_id_mm ≤ 5.
SimCatheter MakeSimCatheter(double sheath_id_mm, double guidewire_od_mm, std::uint64_t seed);

}  // namespace echoservo::live
