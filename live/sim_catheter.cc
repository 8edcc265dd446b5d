#include "live/sim_catheter.h"

#include <stdexcept>

#include "control/experiments/track_experiment.h"
#include "hw/seed_plant.h"

namespace echoservo::live {
namespace {

// The reference is read this far ahead: the tip lags the base command by 6.0–6.2 ms
// through the position loop and the transmission (measured on plant seeds 1–4), and the
// reference is a prediction, so reading it early costs nothing.
constexpr double kTipLagS = 0.006;

}  // namespace

SimCatheter MakeSimCatheter(double sheath_id_mm, double guidewire_od_mm, std::uint64_t seed) {
  if (!(guidewire_od_mm > 0 && sheath_id_mm > guidewire_od_mm && sheath_id_mm <= 5))
    throw std::invalid_argument(
        "--sheath-id/--guidewire-od: must satisfy 0 < guidewire < sheath ≤ 5 mm");
  formats::CatheterConfig catheter = hw::SeedTrackingCatheter();
  catheter.sheath_id_mm = sheath_id_mm;
  catheter.guidewire_od_mm = guidewire_od_mm;
  SimCatheter c;
  c.plant_options = hw::SeedCalibratedPlant(catheter, seed);
  c.plant = std::make_unique<hw::SimulatedCatheter>(c.plant_options);
  c.plant->ResetTo(0.0);
  c.plant->Configure();
  c.plant->Activate();
  c.servo = control::SeedServoConfig(c.plant_options, true);
  c.compensator = std::make_unique<control::StaticInverse>(
      c.plant_options.config.TotalBendRad() * c.plant_options.config.GapMm(),
      c.servo.limits.max_acceleration_mm_s2, kTipLagS);
  return c;
}

}  // namespace echoservo::live
