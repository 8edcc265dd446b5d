// sensor_delay: the tip is measured d seconds late.
#include "hw/effects/builtin_effects.h"

namespace echoservo::hw {
namespace {

class SensorDelay final : public BatchedEffect<SensorDelay> {
 public:
  SensorDelay()
      : BatchedEffect(
            "sensor_delay", EffectStage::kSensor,
            "Tip sensor latency: the recorded tip is the true tip d seconds earlier "
            "(filtering, transport, unsynchronised clocks): tip_meas(t) = tip(t - d).",
            "the whole tip trace is shifted later in time: the residual is proportional to "
            "tip velocity and largest at peak speed, the same in every configuration",
            {{"delay_s", "s", 0.005, 0.0, 0.1, "tip sensor delay"}}) {}

 protected:
  double DoSensorDelayS(const double* p) const override { return p[0]; }
};

}  // namespace

std::unique_ptr<Effect> MakeSensorDelay() { return std::make_unique<SensorDelay>(); }

}  // namespace echoservo::hw
