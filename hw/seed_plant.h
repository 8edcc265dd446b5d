// Plant configurations that reproduce Kesner & Howe's bench (docs/seed_calibration.md).
//
// `SeedCalibratedPlant` is the catheter of the seed's tracking experiments with the
// effects and parameters chosen so that the simulated figures match the published
// ones (uncompensated and iteratively compensated tip MAE on the 1 Hz sine and the
// mitral trajectory): Coulomb + viscous friction with a rubber seal at the tip (a tip
// load), capstan amplification over the bends, the geometric deadzone, axial
// compliance of the guidewire and a finite deadzone traversal time.
// `SeedModelPlant` has only the seed's own model effects (coulomb, viscous, backlash).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "hw/simulated_catheter.h"

namespace echoservo::hw {

// Normal force of the rubber seal at the tip of the seed's evaluation catheter (N).
inline constexpr double kSeedSealLoadN = 1.0;

PlantOptions SeedCalibratedPlant(const formats::CatheterConfig& config, std::uint64_t seed = 1);
PlantOptions SeedModelPlant(const formats::CatheterConfig& config, std::uint64_t seed = 1);

// Replaces a plant's effects (when `effects` is not empty) keeping the configured
// parameter values of the effects that remain, then applies `overrides`
// ("<effect>.<parameter>" = value). Unknown names are rejected when the plant is built.
void SelectEffects(PlantOptions& plant, const std::vector<std::string>& effects,
                   const std::vector<std::pair<std::string, double>>& overrides);

// The seed's evaluation catheter with its tip seal.
formats::CatheterConfig SeedTrackingCatheter();

// Table I of the seed: sheath inner / guidewire outer diameters (mm).
struct SheathGuidewirePair {
  double sheath_id_mm;
  double guidewire_od_mm;
};
const std::vector<SheathGuidewirePair>& TableOneGeometries();
// The seed's bench sweep: every Table I geometry with one bend of 90°, 180° or 360°
// at radius 25 or 50 mm (24 configurations), with the given tip load.
std::vector<formats::CatheterConfig> TableOneSweep(double tip_load_n = 0.0);

}  // namespace echoservo::hw
