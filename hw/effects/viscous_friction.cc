// viscous_friction: F = b · |v|.
#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class ViscousFriction final : public BatchedEffect<ViscousFriction> {
 public:
  ViscousFriction()
      : BatchedEffect("viscous_friction", EffectStage::kFriction,
                      "Lubricated (velocity-proportional) friction of the guidewire in the sheath: "
                      "F = b*|v|, opposing sliding, with v the base speed (mm/s).",
                      "force grows linearly with speed; force residual proportional to velocity",
                      {{"b_n_per_mm_s", "N/(mm/s)", 0.006, 0.0, 0.1, "viscous coefficient"}}) {}

  // The per-sample physics (BatchedEffect).
  static double FrictionN(double speed_mm_s, const EffectContext&, const double* p) {
    return p[0] * speed_mm_s;
  }
};

}  // namespace

std::unique_ptr<Effect> MakeViscousFriction() { return std::make_unique<ViscousFriction>(); }

}  // namespace echoservo::hw
