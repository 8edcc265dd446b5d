// stribeck_friction: extra static friction that fades with speed.
#include <cmath>

#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class StribeckFriction final : public BatchedEffect<StribeckFriction> {
 public:
  StribeckFriction()
      : BatchedEffect(
            "stribeck_friction", EffectStage::kFriction,
            "Static friction above dynamic friction (Stribeck curve): an extra force "
            "dF*exp(-(|v|/v_s)^2) that is full at rest and fades above the Stribeck speed v_s. "
            "The guidewire sticks until the drive force exceeds the breakaway level.",
            "force overshoots just after reversals and at low speed, then settles; stick-slip; "
            "residual concentrated at low speed",
            {{"delta_static_n", "N", 0.4, 0.0, 5.0, "static minus dynamic friction"},
             {"v_stribeck_mm_s", "mm/s", 3.0, 0.05, 100.0, "Stribeck speed"}}) {}

  // The per-sample physics (BatchedEffect).
  static double FrictionN(double speed_mm_s, const EffectContext&, const double* p) {
    const double r = speed_mm_s / p[1];
    return p[0] * std::exp(-r * r);
  }
};

}  // namespace

std::unique_ptr<Effect> MakeStribeckFriction() { return std::make_unique<StribeckFriction>(); }

}  // namespace echoservo::hw
