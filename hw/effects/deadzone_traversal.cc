// deadzone_traversal: the tip approaches the deadzone band with a time constant τ.
#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class DeadzoneTraversal final : public BatchedEffect<DeadzoneTraversal> {
 public:
  DeadzoneTraversal()
      : BatchedEffect(
            "deadzone_traversal", EffectStage::kTipDynamics,
            "Finite-speed deadzone traversal: the guidewire does not settle against the sheath "
            "wall instantly. When the base pushes the band the deadzone allows past the tip, "
            "the tip approaches the band as a first-order lag, d(tip)/dt = (band edge - tip)/tau; "
            "inside the band it stops at once.",
            "engaged motion lags by about v*tau (error proportional to speed), the tip still "
            "stops at once at a reversal; residual concentrated just after reversals and at "
            "high speed",
            {{"tau_s", "s", 0.02, 1e-4, 0.5, "traversal time constant"}}) {}

 protected:
  double DoTraversalTimeConstantS(const double* p) const override { return p[0]; }
};

}  // namespace

std::unique_ptr<Effect> MakeDeadzoneTraversal() { return std::make_unique<DeadzoneTraversal>(); }

}  // namespace echoservo::hw
