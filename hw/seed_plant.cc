#include "hw/seed_plant.h"

#include <algorithm>

namespace echoservo::hw {

PlantOptions SeedCalibratedPlant(const formats::CatheterConfig& config, std::uint64_t seed) {
  PlantOptions o;
  o.config = config;
  o.seed = seed;
  o.effects = {"coulomb_friction",     "viscous_friction", "capstan_friction",
               "guidewire_compliance", "backlash",         "deadzone_traversal"};
  o.parameters = {
      {"coulomb_friction.f0_n", 0.55},           // wall friction along the 85 cm sheath
      {"coulomb_friction.mu_tip", 0.3},          // rubber seal on the guidewire
      {"viscous_friction.b_n_per_mm_s", 0.006},  // the seed's typical viscous term
      {"capstan_friction.mu", 0.05},
      {"guidewire_compliance.k_n_per_mm", 30.0},
      {"deadzone_traversal.tau_s", 0.003},
  };
  return o;
}

PlantOptions SeedModelPlant(const formats::CatheterConfig& config, std::uint64_t seed) {
  PlantOptions o;
  o.config = config;
  o.seed = seed;
  o.effects = {"coulomb_friction", "viscous_friction", "backlash"};
  o.parameters = {{"coulomb_friction.f0_n", 1.0}, {"viscous_friction.b_n_per_mm_s", 0.006}};
  return o;
}

void SelectEffects(PlantOptions& plant, const std::vector<std::string>& effects,
                   const std::vector<std::pair<std::string, double>>& overrides) {
  if (!effects.empty()) {
    plant.effects = effects;
    std::erase_if(plant.parameters, [&](const auto& p) {
      const std::string effect = p.first.substr(0, p.first.find('.'));
      return std::find(effects.begin(), effects.end(), effect) == effects.end();
    });
  }
  for (const auto& p : overrides) plant.parameters.push_back(p);
}

formats::CatheterConfig SeedTrackingCatheter() {
  formats::CatheterConfig c = formats::CatheterConfig::SeedEvaluation();
  c.tip_load_n = kSeedSealLoadN;
  return c;
}

const std::vector<SheathGuidewirePair>& TableOneGeometries() {
  static const std::vector<SheathGuidewirePair> pairs = {
      {1.59, 0.76}, {1.59, 1.50}, {2.38, 1.50}, {2.38, 2.23}};
  return pairs;
}

std::vector<formats::CatheterConfig> TableOneSweep(double tip_load_n) {
  std::vector<formats::CatheterConfig> configs;
  for (const SheathGuidewirePair& g : TableOneGeometries()) {
    for (double angle : {90.0, 180.0, 360.0}) {
      for (double radius : {25.0, 50.0}) {
        formats::CatheterConfig c;
        c.sheath_id_mm = g.sheath_id_mm;
        c.guidewire_od_mm = g.guidewire_od_mm;
        c.bends = {{angle, radius}};
        c.tip_load_n = tip_load_n;
        configs.push_back(c);
      }
    }
  }
  return configs;
}

}  // namespace echoservo::hw
