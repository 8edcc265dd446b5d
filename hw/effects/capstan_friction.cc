// capstan_friction: friction multiplied by exp(mu · θ) (Euler–Eytelwein).
#include <cmath>

#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class CapstanFriction final : public BatchedEffect<CapstanFriction> {
 public:
  CapstanFriction()
      : BatchedEffect(
            "capstan_friction", EffectStage::kFriction,
            "Capstan (Euler-Eytelwein) amplification: a guidewire pulled around bends of total "
            "angle theta needs exp(mu*theta) times the force at the far end, so every friction "
            "term is multiplied by exp(mu*theta).",
            "friction level grows exponentially with total bend angle at fixed gap and load; "
            "force residual scales with the friction level",
            {{"mu", "1", 0.1, 0.0, 1.0, "wrap friction coefficient"}}) {}

 protected:
  double DoFrictionScale(const EffectContext& c, const double* p) const override {
    return std::exp(p[0] * c.total_bend_rad);
  }
};

}  // namespace

std::unique_ptr<Effect> MakeCapstanFriction() { return std::make_unique<CapstanFriction>(); }

}  // namespace echoservo::hw
