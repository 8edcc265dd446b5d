// guidewire_compliance: axial spring between base and tip, tip lags by F/k.
#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class GuidewireCompliance final : public BatchedEffect<GuidewireCompliance> {
 public:
  GuidewireCompliance()
      : BatchedEffect(
            "guidewire_compliance", EffectStage::kCompliance,
            "Axial compliance of the guidewire: it compresses and stretches like a spring of "
            "stiffness k under the friction force F it carries, so the tip end lags the base by "
            "F/k: drive = base - F/k.",
            "tip lags the base by an amount proportional to the measured force: a widened "
            "hysteresis loop that grows with friction and speed, a tip step at every force "
            "reversal",
            {{"k_n_per_mm", "N/mm", 5.0, 0.05, 1000.0, "axial stiffness"}}) {}

  // The per-sample physics (BatchedEffect).
  static double OffsetMm(double friction_force_n, const EffectContext&, const double* p) {
    return -friction_force_n / p[0];
  }
};

}  // namespace

std::unique_ptr<Effect> MakeGuidewireCompliance() {
  return std::make_unique<GuidewireCompliance>();
}

}  // namespace echoservo::hw
