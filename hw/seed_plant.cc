#include "hw/seed_plant.h"

namespace echoservo::hw {

PlantOptions SeedCalibratedPlant(const CatheterConfig& config, std::uint64_t seed) {
  PlantOptions o;
  o.config = config;
  o.seed = seed;
  o.effects = {"coulomb_friction", "viscous_friction", "capstan_friction",
               "guidewire_compliance", "backlash", "deadzone_traversal"};
  o.parameters = {
      {"coulomb_friction.f0_n", 0.55},          // wall friction along the 85 cm sheath
      {"coulomb_friction.mu_tip", 0.3},         // rubber seal on the guidewire
      {"viscous_friction.b_n_per_mm_s", 0.006}, // the seed's typical viscous term
      {"capstan_friction.mu", 0.05},
      {"guidewire_compliance.k_n_per_mm", 30.0},
      {"deadzone_traversal.tau_s", 0.005},
  };
  return o;
}

PlantOptions SeedModelPlant(const CatheterConfig& config, std::uint64_t seed) {
  PlantOptions o;
  o.config = config;
  o.seed = seed;
  o.effects = {"coulomb_friction", "viscous_friction", "backlash"};
  o.parameters = {{"coulomb_friction.f0_n", 1.0}, {"viscous_friction.b_n_per_mm_s", 0.006}};
  return o;
}

CatheterConfig SeedTrackingCatheter() {
  CatheterConfig c = CatheterConfig::SeedEvaluation();
  c.tip_load_n = kSeedSealLoadN;
  return c;
}

}  // namespace echoservo::hw
