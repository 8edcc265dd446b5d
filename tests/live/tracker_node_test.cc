// The tracker node on rendered volumes (live/tracker_node.h): the static scene that
// `echoservo scanner` serves shows no heartbeat (the node says so and would publish a hold
// at confidence 0), the demo's beating annulus shows one within three beats.
#include "live/tracker_node.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "imaging/sim/simulated_scanner.h"
#include "live/sim_scene.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo::live {
namespace {

// 10 vol/s keeps the rendering short; the significance test adapts its harmonics to it.
constexpr double kRateHz = 10.0;

#ifdef ECHOSERVO_SANITIZED
constexpr int kVolumes = 24;  // 2.3 s: the sanitizer build renders 3–10× slower
#else
constexpr int kVolumes = 36;  // 3.5 s
#endif

TEST(TrackerNode, StaticSceneHasNoHeartbeat) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "the significance test's no-heartbeat path runs under the sanitizers in "
      "tests/estimation/heartbeat_significance_test.cc; this case checks its statistics");
  imaging::sim::SimulatedScannerOptions so;  // what `echoservo scanner` serves: nothing moves
  so.rate_hz = kRateHz;
  imaging::sim::SimulatedScanner scanner(so);
  TrackerNode node({}, nullptr, nullptr);
  int evaluated = 0;
  for (int i = 0; i < kVolumes; ++i) {
    const std::optional<imaging::SourceFrame> f = scanner.Next();
    ASSERT_TRUE(f);
    const double t = i / kRateHz;
    const TrackedVolume r = node.Process(f->volume, t, t, [t] { return t; });
    ASSERT_TRUE(r.measured) << r.error;
    EXPECT_FALSE(node.heartbeat().significant) << "volume " << i << ": " << node.heartbeat().reason;
    evaluated += node.heartbeat().snr_threshold > 0.0;
  }
  std::printf("static scene: %s (noise %.3f mm)\n", node.heartbeat().reason.c_str(),
              node.heartbeat().noise_mm);
  EXPECT_GT(evaluated, 0);  // the test ran on the trace, not only collected it
  EXPECT_EQ(node.heartbeat().confidence(), 0.0);
  EXPECT_NE(node.heartbeat().reason.find("no significant heartbeat"), std::string::npos);
}

TEST(TrackerNode, BeatingAnnulusHasAHeartbeatWithinThreeBeats) {
  constexpr double kHeartRateBpm = 72.0;
  SimScene scene({kRateHz, kHeartRateBpm, 10.0, 8.0, 1});
  TrackerNode node({}, nullptr, nullptr);
  double first_s = -1.0;
  for (int i = 0; i < 45 && first_s < 0.0; ++i) {  // 4.4 s: 5 beats
    const double t = i / kRateHz;
    const imaging::SourceFrame f = scene.Render(t);
    const TrackedVolume r = node.Process(f.volume, t, t, [t] { return t; });
    ASSERT_TRUE(r.measured) << r.error;
    if (node.heartbeat().significant) first_s = t;
  }
  ASSERT_GE(first_s, 0.0) << node.heartbeat().reason;
  std::printf("beating annulus: %s after %.1f s\n", node.heartbeat().reason.c_str(), first_s);
  EXPECT_LE(first_s * kHeartRateBpm / 60.0, 3.0);
  EXPECT_NEAR(node.heartbeat().rate_hz, kHeartRateBpm / 60.0, 0.15);
  EXPECT_GT(node.heartbeat().confidence(), 0.99);
}

}  // namespace
}  // namespace echoservo::live
