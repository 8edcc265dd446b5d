// The two runtimes every command runs (live/servo_runtime.h, live/tracker_runtime.h): the
// servo's cycles on simulated and real time, its in-process estimate feed, and the tracker's
// source → node → sinks path with its recorder.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <vector>

#include "live/servo_node.h"
#include "live/servo_runtime.h"
#include "live/sim_catheter.h"
#include "live/sim_scene.h"
#include "live/tracker_runtime.h"
#include "live/tracker_source.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::live {
namespace {

// A 1 Hz, ±2 mm target at 10 mm acquired at `t_acq`, the tip seen where the catheter is.
link::TargetEstimateSample RuntimeEstimate(double t_acq, std::uint64_t seq, double tip_mm) {
  link::TargetEstimateSample s;
  s.sequence_number = seq;
  s.acquisition_time_s = s.publication_time_s = t_acq;
  s.axis = Eigen::Vector3d::UnitZ();
  s.target_mm = Eigen::Vector3d(0, 0, 10);
  s.tip_mm = Eigen::Vector3d(0, 0, tip_mm);
  s.motion.frequency_hz = 1.0;
  s.motion.offset_mm = 10.0;
  s.motion.cos_mm = {0.0};
  s.motion.sin_mm = {2.0};
  s.motion.valid_until_s = t_acq + 0.5;
  s.confidence = 0.9;
  return s;
}

struct ServoRig {
  SimCatheter catheter = MakeSimCatheter(1.59, 1.50, 1);
  ServoNode node;
  ServoRig()
      : node(
            *catheter.plant, catheter.servo, std::move(catheter.compensator),
            [] {
              ServoNodeOptions o;
              o.follower.standoff_mm = 2.0;
              o.auto_enable = true;
              return o;
            }(),
            nullptr) {}
  double Tip() const { return catheter.plant->state(hw::iface::kTipPosition); }
};

TEST(ServoRuntime, SimulatedTimeRunsEveryCycleInOrderAndDeliversEstimatesWhenDue) {
  ServoRig rig;
  DelayedEstimates estimates;
  ServoRuntimeOptions o;
  o.clock = ServoClock::kSimulated;
  o.t0_s = 5.0;
  o.duration_s = 3.0;
  o.estimates = &estimates;
  const double period = rig.catheter.servo.period_s;
  std::vector<double> before_t, after_t;
  std::uint64_t seq = 0;
  std::optional<double> first_applied_s;
  double err_sq = 0.0;
  std::size_t err_n = 0;
  const ServoRunResult r =
      ServoRuntime(rig.node, o)
          .Run(
              [&](std::uint64_t k, double t) {
                before_t.push_back(t);
                // A volume every 40 ms, delivered 60 ms after its acquisition.
                if (k % 40 == 0) estimates.Push(RuntimeEstimate(t, ++seq, rig.Tip()), t + 0.06);
              },
              [&](std::uint64_t, double t, const ServoCycle& c) {
                after_t.push_back(t);
                if (rig.node.stats().estimates_accepted > 0 && !first_applied_s)
                  first_applied_s = t;
                if (t > 6.5) {  // following for 1.4 s: the tip at the target less the standoff
                  const double e = c.record.tip_mm - c.record.reference_mm;
                  err_sq += e * e;
                  ++err_n;
                }
              });
  const std::size_t cycles = static_cast<std::size_t>(std::llround(3.0 / period)) + 1;
  EXPECT_EQ(r.cycles, cycles);
  ASSERT_EQ(before_t.size(), cycles);
  ASSERT_EQ(after_t, before_t);
  for (std::size_t k = 0; k < before_t.size(); ++k)
    EXPECT_NEAR(before_t[k], 5.0 + static_cast<double>(k) * period, 1e-9);
  ASSERT_TRUE(first_applied_s.has_value());
  EXPECT_NEAR(*first_applied_s, 5.06, 0.5 * period);  // the first estimate's delivery time
  EXPECT_EQ(rig.node.stats().cycles, cycles);
  ASSERT_GT(err_n, 1000u);
  // The seed's servo tracks a 2 mm, 1 Hz reference within a small fraction of its amplitude.
  EXPECT_LT(std::sqrt(err_sq / static_cast<double>(err_n)), 0.2);
}

TEST(ServoRuntime, DelayedEstimatesGoOutInDeliveryOrder) {
  ServoRig rig;
  rig.node.Start(0.0);
  DelayedEstimates q;
  q.Push(RuntimeEstimate(0.0, 2, 0.0), 0.2);
  q.Push(RuntimeEstimate(0.0, 1, 0.0), 0.1);
  q.Push(RuntimeEstimate(0.0, 3, 0.0), 0.3);
  EXPECT_EQ(q.Deliver(rig.node, 0.05), 0u);
  EXPECT_EQ(q.Deliver(rig.node, 0.2), 2u);
  EXPECT_EQ(q.pending(), 1u);
  EXPECT_EQ(q.Deliver(rig.node, 1.0), 1u);
}

TEST(ServoRuntime, RealTimeKeepsToTheCycleClockAndTimesEveryCycle) {
  ServoRig rig;
  const PipelineClock clock(0.0);
  ServoRuntimeOptions o;
  o.clock = ServoClock::kRealtime;
  o.pipeline_clock = &clock;
  o.realtime.enabled = false;  // an ordinary thread: nothing asked of the system
  o.duration_s = 0.2;
  const auto start = std::chrono::steady_clock::now();
  const ServoRunResult r = ServoRuntime(rig.node, o).Run(nullptr, nullptr);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(r.cycles, 201u);
  EXPECT_GE(wall_s, 0.195);  // cycle 200 is due at 0.2 s on the pipeline clock
  EXPECT_EQ(r.timing.cycles, 201u);
  EXPECT_FALSE(r.realtime.fifo);
}

TEST(ServoRuntime, AStopConditionEndsTheLoopAtTheNextCycle) {
  ServoRig rig;
  ServoRuntimeOptions o;
  o.clock = ServoClock::kSimulated;
  std::uint64_t seen = 0;
  o.stop = [&seen] { return seen >= 10; };
  const ServoRunResult r =
      ServoRuntime(rig.node, o).Run(nullptr, [&](std::uint64_t, double, const ServoCycle&) {
        ++seen;
      });
  EXPECT_EQ(r.cycles, 10u);
}

TEST(ServoRuntime, BadOptionsAreNamed) {
  using testing::InvalidArgumentMessage;
  ServoRig rig;
  ServoRuntimeOptions o;
  o.clock = ServoClock::kRealtime;
  testing::ExpectContains(InvalidArgumentMessage([&] { ServoRuntime(rig.node, o); }),
                          "pipeline_clock");
  o.clock = ServoClock::kSimulated;
  testing::ExpectContains(InvalidArgumentMessage([&] { ServoRuntime(rig.node, o); }), "duration_s");
  o.duration_s = -1.0;
  testing::ExpectContains(InvalidArgumentMessage([&] { ServoRuntime(rig.node, o); }),
                          "duration_s must be ≥ 0 s");
}

// The simulated scanner through the tracker runtime: every volume delivered is processed once
// and handed to the sink in order, and the recorder writes what the tracker received.
TEST(TrackerRuntime, TheSimulatedScannerThroughTheNodeToItsSinksAndRecorder) {
  const testing::TempDir dir("tracker_runtime", true);
  SimScene scene({25.0, 60.0, 10.0, 8.0, 1});
  const PipelineClock clock(0.1);
  SimScannerSource source(scene, clock, {25.0, 0.05, 0.10, 1.2, 1});
  TrackerRuntimeOptions o;
  o.record_to = dir.path() / "volumes.igs.mhd";
  std::vector<double> stamps;
  std::uint64_t found = 0;
  o.on_tracked = [&](const TrackedVolume& r, const SourceVolume& v, double process_ms) {
    EXPECT_GE(process_ms, 0.0);
    EXPECT_GE(v.arrived_s, v.stamp_s);  // delivered after the imaging delay
    stamps.push_back(v.stamp_s);
    found += r.detection.found && r.detection.target_found;
  };
  TrackerRuntime runtime(o);
  const TrackerRunResult r = runtime.Run(source);
  EXPECT_TRUE(source.finished());
  // 1.2 s at 25 vol/s = 30 acquisition slots, each acquired or counted missed; a slow host
  // (a sanitizer build) supersedes volumes, which are counted, never lost silently.
  EXPECT_GE(r.source.acquired + r.source.missed, 28u);
  ASSERT_GE(stamps.size(), 3u);
  EXPECT_EQ(r.stats.volumes, stamps.size());
  EXPECT_EQ(r.source.acquired, stamps.size() + r.source.dropped);
  for (std::size_t i = 1; i < stamps.size(); ++i) EXPECT_GT(stamps[i], stamps[i - 1]);
  EXPECT_GE(found, stamps.size() - 2);  // the water tank's catheter and target are in view
  EXPECT_EQ(r.recorder.written + r.recorder.dropped, stamps.size());
  EXPECT_GT(r.recorder.written, 0u);
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "volumes.igs.mhd"));
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "volumes.json"));
}

TEST(TrackerRuntime, AStopConditionEndsTheRunAndStopsTheSource) {
  SimScene scene({25.0, 60.0, 10.0, 8.0, 1});
  const PipelineClock clock(0.1);
  SimScannerSource source(scene, clock, {25.0, 0.05, 0.10, 30.0, 1});
  TrackerRuntimeOptions o;
  std::atomic<int> seen{0};
  o.on_tracked = [&](const TrackedVolume&, const SourceVolume&, double) { ++seen; };
  o.stop = [&seen] { return seen >= 3; };
  TrackerRuntime runtime(o);
  const auto start = std::chrono::steady_clock::now();
  const TrackerRunResult r = runtime.Run(source);
  EXPECT_EQ(r.stats.volumes, 3u);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
}

}  // namespace
}  // namespace echoservo::live
