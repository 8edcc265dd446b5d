#include "hw/effect.h"

namespace echoservo::hw {

std::string_view ToString(EffectStage stage) {
  switch (stage) {
    case EffectStage::kFriction:
      return "friction";
    case EffectStage::kCompliance:
      return "compliance";
    case EffectStage::kBacklash:
      return "backlash";
    case EffectStage::kTipDynamics:
      return "tip dynamics";
    case EffectStage::kSensor:
      return "sensor";
  }
  return "unknown";
}

EffectContext EffectContext::From(const formats::CatheterConfig& config) {
  EffectContext c;
  c.total_bend_rad = config.TotalBendRad();
  c.gap_mm = config.GapMm();
  c.tip_load_n = config.tip_load_n;
  return c;
}

}  // namespace echoservo::hw
