// tip_sensor_scale: tip sensor gain error.
#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class TipSensorScale final : public BatchedEffect<TipSensorScale> {
 public:
  TipSensorScale()
      : BatchedEffect("tip_sensor_scale", EffectStage::kSensor,
                      "Tip sensor gain error (a miscalibrated potentiometer or tracker scale): "
                      "tip_meas = s * tip.",
                      "residual proportional to tip position (largest at the extremes of travel), "
                      "amplitude of the tip trace off by a constant factor",
                      {{"scale", "1", 1.03, 0.5, 2.0, "tip sensor gain"}}) {}

 protected:
  double DoSensorScale(const double* p) const override { return p[0]; }
};

}  // namespace

std::unique_ptr<Effect> MakeTipSensorScale() { return std::make_unique<TipSensorScale>(); }

}  // namespace echoservo::hw
