// backlash: deadzone of width B = θ · (D_sheath − D_guidewire) (the seed's eq. 2).
#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class Backlash final : public BatchedEffect<Backlash> {
 public:
  Backlash()
      : BatchedEffect(
            "backlash", EffectStage::kBacklash,
            "Geometric backlash: in a bent sheath the guidewire takes the inside or the outside "
            "of each bend depending on the direction it was last pushed; switching sides "
            "absorbs base motion without moving the tip. Deadzone width B = theta*gap with "
            "theta the total bend angle (rad) and gap = D_sheath - D_guidewire (mm).",
            "tip stands still for a base travel B after every reversal: a hysteresis loop of "
            "width B in tip vs base, proportional to total bend angle and gap",
            {}) {}

 protected:
  double DoBacklashWidthMm(double, double, const EffectContext& c, const double*) const override {
    return c.total_bend_rad * c.gap_mm;
  }
};

}  // namespace

std::unique_ptr<Effect> MakeBacklash() { return std::make_unique<Backlash>(); }

}  // namespace echoservo::hw
