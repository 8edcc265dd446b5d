// An example effect plugin (hw/effect_plugin.h): `quadratic_drag`, friction that grows
// with the square of the base speed, F = c·v² (N, v in mm/s), as a turbulent-like drag of
// the guidewire in a fluid-filled sheath would. Built as a MODULE library when the tests
// are built; it links no project library and calls the loading program's hw code.
#include <memory>

#include "hw/effect_plugin.h"
#include "hw/effects/builtin_effects.h"

namespace {

using echoservo::hw::DescribedEffect;
using echoservo::hw::EffectContext;
using echoservo::hw::EffectStage;

class QuadraticDrag final : public DescribedEffect {
 public:
  QuadraticDrag()
      : DescribedEffect(
            "quadratic_drag", EffectStage::kFriction,
            "Drag growing with the square of the base speed: F = c*v^2, opposing "
            "sliding, with v the base speed (mm/s).",
            "force residual growing with the square of the speed; flat near rest",
            {{"c_n_per_mm2_s2", "N/(mm/s)^2", 1e-5, 0.0, 1e-3, "quadratic drag coefficient"}}) {}

 protected:
  double DoFrictionMagnitudeN(double speed_mm_s, const EffectContext&,
                              const double* p) const override {
    return p[0] * speed_mm_s * speed_mm_s;
  }
};

}  // namespace

extern "C" int echoservo_effect_plugin_abi() { return echoservo::hw::kEffectPluginAbi; }

extern "C" void echoservo_register_effects(echoservo::hw::EffectRegistry& registry) {
  registry.Register("quadratic_drag", [] { return std::make_unique<QuadraticDrag>(); });
}
