// friction_backlash: B = θ · gap · (a + b · F_friction).
#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class FrictionBacklash final : public BatchedEffect<FrictionBacklash> {
 public:
  FrictionBacklash()
      : BatchedEffect(
            "friction_backlash", EffectStage::kBacklash,
            "Friction-dependent backlash: under friction the sheath deforms and the guidewire "
            "buckles inside it, so the deadzone widens with the friction level F (breakaway "
            "friction, N): B = theta*gap*(a + b*F). Replaces the purely geometric width.",
            "measured hysteresis widths deviate from theta*gap in proportion to the friction "
            "level: too narrow a model for high-friction configurations (tip load, small gap, "
            "many bends), too wide for low-friction ones",
            {{"a", "1", 0.6, 0.0, 3.0, "width factor at zero friction"},
             {"b_per_n", "1/N", 0.3, 0.0, 3.0, "width increase per newton of friction"}}) {}

 protected:
  double DoBacklashWidthMm(double, double friction_level_n, const EffectContext& c,
                           const double* p) const override {
    const double factor = p[0] + p[1] * friction_level_n;
    return c.total_bend_rad * c.gap_mm * (factor > 0.0 ? factor : 0.0);
  }
};

}  // namespace

std::unique_ptr<Effect> MakeFrictionBacklash() { return std::make_unique<FrictionBacklash>(); }

}  // namespace echoservo::hw
