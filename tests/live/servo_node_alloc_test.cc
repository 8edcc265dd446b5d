// live::ServoNode once warm does not allocate on the servo thread: a node on the simulated
// catheter, with a DDS participant (its state publisher thread and its command queue in
// use), fed by a second participant the way the tracker and an operator feed it (an
// estimate every 40 ms, standoff changes, a STOP and an ENABLE), paced at 1 kHz on the
// steady clock with the deadline watchdog fed as the loop driver feeds it. The global
// operator new is replaced (tests/control/alloc_counter.h, per-thread counts) in this
// executable only. Waits are bounded by generous timeouts; nothing asserts on timing.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <thread>

#include "hw/hardware_interface.h"
#include "link/clock.h"
#include "link/dds_link.h"
#include "live/servo_node.h"
#include "live/sim_catheter.h"
#include "tests/control/alloc_counter.h"
#include "tests/link/link_test_util.h"

namespace echoservo::live {
namespace {

using Clock = std::chrono::steady_clock;
using echoservo::testing::Eventually;
using echoservo::testing::ProcessDomain;
using echoservo::testing::ThreadAllocations;

constexpr double kPeriodS = 1e-3;
constexpr std::uint64_t kWarmCycles = 1000;      // 1 s
constexpr std::uint64_t kMeasuredCycles = 2000;  // 2 s

link::ParticipantOptions Loopback(const char* name) {
  link::ParticipantOptions o;
  o.domain_id = ProcessDomain();
  o.name = name;
  o.loopback_only = true;
  return o;
}

// The target at 10 + 2·sin(2π·1 Hz·t) mm (node time t = link time − `offset_s`), the tip
// seen where the catheter's is, acquired 1 ms before publication (link clock).
link::TargetEstimateSample Estimate(std::uint64_t seq, double offset_s, double tip_mm) {
  const double now = link::NowS();
  link::TargetEstimateSample s;
  s.sequence_number = seq;
  s.acquisition_time_s = now - 0.001;
  s.publication_time_s = now;
  s.axis = Eigen::Vector3d::UnitZ();
  s.target_mm = Eigen::Vector3d(0, 0, 10);
  s.tip_mm = Eigen::Vector3d(0, 0, tip_mm);
  s.motion.t0_s = offset_s;
  s.motion.frequency_hz = 1.0;
  s.motion.offset_mm = 10.0;
  s.motion.cos_mm = {0.0, 0.1};
  s.motion.sin_mm = {2.0, 0.0};
  s.motion.valid_until_s = s.acquisition_time_s + 0.5;
  s.confidence = 0.9;
  return s;
}

link::ServoCommandSample Command(std::uint64_t seq, link::ServoAction a, double standoff_mm) {
  link::ServoCommandSample c;
  c.sequence_number = seq;
  c.stamp_s = link::NowS();
  c.action = a;
  c.standoff_mm = standoff_mm;
  return c;
}

TEST(ServoNodeRealTime, CycleDoesNotAllocateOnceWarm) {
  link::Participant servo_participant(Loopback("alloc_test_servo"));
  link::Participant peer(Loopback("alloc_test_peer"));
  SimCatheter catheter = MakeSimCatheter(1.59, 1.50, 1);
  hw::SimulatedCatheter& plant = *catheter.plant;
  const std::size_t tip_index = plant.StateIndex(hw::iface::kTipPosition);
  // Node time 0 is link time link_offset_s (and steady time `start`).
  const double link_offset_s = link::NowS();
  const Clock::time_point start = Clock::now();
  ServoNodeOptions o;
  o.follower.standoff_mm = 3.0;
  o.link_offset_s = link_offset_s;
  ServoNode node(plant, catheter.servo, std::move(catheter.compensator), o, &servo_participant);

  auto target_pub = std::make_unique<link::TargetPublisher>(peer);
  link::CommandPublisher command_pub(peer);
  link::StateSubscriber state_sub(peer);
  ASSERT_TRUE(target_pub->WaitForSubscribers(1, 15.0));
  ASSERT_TRUE(command_pub.WaitForSubscribers(1, 15.0));
  ASSERT_TRUE(state_sub.WaitForPublishers(1, 15.0));
  ASSERT_TRUE(Eventually([&] { return node.target_link_stats().matched_publishers == 1; }));

  // The peer: the tracker's estimates every 40 ms, an operator's commands through the run.
  std::atomic<double> tip_mm{0.0};
  std::atomic<std::uint64_t> cycle{0}, first_cycle{0};
  std::atomic<bool> running{true};
  std::uint64_t commands_sent = 0;
  std::thread peer_thread([&] {
    std::uint64_t seq = 0, last_command_cycle = 0;
    while (running.load()) {
      target_pub->Publish(Estimate(++seq, link_offset_s, tip_mm.load()));
      const std::uint64_t k = cycle.load() - std::min(cycle.load(), first_cycle.load());
      if (commands_sent == 0) {
        command_pub.Publish(Command(++commands_sent, link::ServoAction::kEnable, 3.0));
      } else if (k >= kWarmCycles + 1500 && k < kWarmCycles + 1540 &&
                 last_command_cycle < kWarmCycles + 1500) {
        command_pub.Publish(Command(++commands_sent, link::ServoAction::kStop, 0.0));
        last_command_cycle = k;
      } else if (k >= kWarmCycles + 1700 && last_command_cycle < kWarmCycles + 1700) {
        command_pub.Publish(Command(++commands_sent, link::ServoAction::kEnable, 3.0));
        last_command_cycle = k;
      } else if (k >= last_command_cycle + 200 && k < kWarmCycles + 1500) {
        const double standoff = commands_sent % 2 ? 3.5 : 3.0;
        command_pub.Publish(Command(++commands_sent, link::ServoAction::kSetStandoff, standoff));
        last_command_cycle = k;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(40));
    }
  });

  // The servo thread (this one), as ServoCycleClock drives it.
  std::uint64_t allocations_before = 0, allocations = 0, tracking_cycles = 0;
  auto since_start_s = [&](Clock::time_point p) {
    return std::chrono::duration<double>(p - start).count();
  };
  // The first cycle after the matching above.
  const auto k0 = static_cast<std::uint64_t>(std::ceil(since_start_s(Clock::now()) / kPeriodS));
  node.Start(static_cast<double>(k0) * kPeriodS);
  first_cycle.store(k0);
  cycle.store(k0);
  for (std::uint64_t k = k0; k < k0 + kWarmCycles + kMeasuredCycles; ++k) {
    if (k == k0 + kWarmCycles) allocations_before = ThreadAllocations();
    const double t = static_cast<double>(k) * kPeriodS;
    std::this_thread::sleep_until(
        start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(t)));
    const double woke = since_start_s(Clock::now());
    node.NoteWake(woke, woke - t);
    const ServoCycle c = node.Cycle(t, k);
    tracking_cycles += k >= k0 + kWarmCycles && c.mode == link::ServoMode::kTracking;
    tip_mm.store(plant.state(tip_index));
    cycle.store(k);
    const double end = since_start_s(Clock::now());
    node.NoteCycleEnd(end, end > t + kPeriodS);
  }
  allocations = ThreadAllocations() - allocations_before;
  running = false;
  peer_thread.join();

  EXPECT_EQ(allocations, 0u) << "the servo cycle allocated " << allocations << " times in "
                             << kMeasuredCycles << " warm cycles";
  const ServoNodeStats s = node.stats();
  std::printf(
      "servo cycles %llu: %llu estimates accepted, %llu commands, %llu tracking, "
      "%llu states, %llu deadline holds\n",
      static_cast<unsigned long long>(s.cycles),
      static_cast<unsigned long long>(s.estimates_accepted),
      static_cast<unsigned long long>(s.commands_applied),
      static_cast<unsigned long long>(tracking_cycles),
      static_cast<unsigned long long>(s.states_published),
      static_cast<unsigned long long>(s.deadline_holds));
  // The paths the measurement covered were taken: estimates (25/s), the operator's
  // commands through the queue, states through the publisher thread (100/s).
  const link::SubscriberStats ls = node.target_link_stats();
  EXPECT_GE(s.estimates_accepted, 40u)
      << "link: received " << ls.received << ", accepted " << ls.validation.accepted
      << ", rejected by the follower " << s.estimates_rejected;
  EXPECT_GT(tracking_cycles, 0u);
  ASSERT_TRUE(Eventually([&] { return node.commands_queued() == commands_sent; }));
  std::uint64_t k = k0 + kWarmCycles + kMeasuredCycles;
  node.Cycle(static_cast<double>(k) * kPeriodS, k);
  ++k;
  EXPECT_EQ(node.stats().commands_applied, commands_sent);
  EXPECT_GE(commands_sent, 8u);
  ASSERT_TRUE(node.WaitStatesPublished(5.0));
  const double states_written = static_cast<double>(s.cycles) * kPeriodS * o.state_rate_hz;
  EXPECT_NEAR(static_cast<double>(node.stats().states_published), states_written,
              0.05 * states_written);
  EXPECT_TRUE(Eventually([&] { return state_sub.stats().received > 0; }));

  // The tracker leaves: the cycle sees it without the subscriber's lock (within the
  // liveliness lease, 0.5 s, at the state rate).
  EXPECT_FALSE(node.tracker_gone());
  target_pub.reset();
  const Clock::time_point left = Clock::now();
  while (!node.tracker_gone() && Clock::now() - left < std::chrono::seconds(10)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    node.Cycle(static_cast<double>(k) * kPeriodS, k);
    ++k;
  }
  EXPECT_TRUE(node.tracker_gone());
}

}  // namespace
}  // namespace echoservo::live
