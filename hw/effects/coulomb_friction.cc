// coulomb_friction: F = f0 + mu_tip · N_tip, opposing sliding, independent of speed.
#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class CoulombFriction final : public BatchedEffect<CoulombFriction> {
 public:
  CoulombFriction()
      : BatchedEffect(
            "coulomb_friction", EffectStage::kFriction,
            "Dry sliding friction between guidewire and sheath: a constant part f0 from the "
            "wall contact along the whole sheath plus Coulomb's law mu_tip*N for the normal force "
            "N (tip_load_n) pressing the sheath on the guidewire near the tip. F = f0 + mu_tip*N, "
            "opposing the direction of sliding, independent of speed.",
            "force is a square wave in the direction of motion: a step of 2F at every reversal, "
            "flat at constant speed; the level grows with tip load",
            {{"f0_n", "N", 1.0, 0.0, 10.0, "constant Coulomb friction"},
             {"mu_tip", "1", 0.3, 0.0, 2.0, "friction coefficient for the tip load"}}) {}

  // The per-sample physics (BatchedEffect).
  static double FrictionN(double, const EffectContext& c, const double* p) {
    return p[0] + p[1] * c.tip_load_n;
  }
};

}  // namespace

std::unique_ptr<Effect> MakeCoulombFriction() { return std::make_unique<CoulombFriction>(); }

}  // namespace echoservo::hw
