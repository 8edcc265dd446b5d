// live::SimScene's plant-tip history, which the demo's servo thread writes every cycle and
// the renderer and the tracker read: linear interpolation at a volume's acquisition time,
// out-of-order samples ignored, the last second kept in a fixed ring.
#include "live/sim_scene.h"

#include <gtest/gtest.h>

namespace echoservo::live {
namespace {

TEST(SimScene, PlantTipHistoryInterpolatesAndKeepsTheLastSecond) {
  SimScene scene(SimSceneOptions{});
  EXPECT_EQ(scene.PlantTipAt(1.0), 0.0);  // nothing yet
  // 5 s at 1 kHz of a ramp tip = 2 mm/s · t: more samples than the ring's 4096 (it wraps).
  for (int k = 0; k <= 5000; ++k) scene.SetPlantTip(1e-3 * k, 2e-3 * k);
  EXPECT_NEAR(scene.PlantTipAt(4.5005), 9.001, 1e-9);  // between two samples
  EXPECT_NEAR(scene.PlantTipAt(4.2), 8.4, 1e-9);
  EXPECT_NEAR(scene.PlantTipAt(5.5), 10.0, 1e-12);  // after the newest: the newest
  // Older than a second before the newest: the oldest kept, from t = 4 s on.
  EXPECT_NEAR(scene.PlantTipAt(0.5), 8.0, 1e-9);
  scene.SetPlantTip(4.9, 100.0);  // out of order: ignored
  EXPECT_NEAR(scene.PlantTipAt(4.9), 9.8, 1e-9);
}

}  // namespace
}  // namespace echoservo::live
