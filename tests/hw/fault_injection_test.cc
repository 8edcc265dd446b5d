// hw::FaultInjectingHardware: mirrors the wrapped hardware's interfaces and lifecycle,
// passes readings through outside the fault windows and corrupts them inside (NaN, ±inf,
// frozen at the last good value, offset, or a slow read), counting each corrupted sample.
#include "hw/fault_injection.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "hw/seed_plant.h"
#include "hw/simulated_catheter.h"

namespace echoservo::hw {
namespace {

struct Rig {
  SimulatedCatheter plant{SeedCalibratedPlant(SeedTrackingCatheter(), 1)};
  std::size_t force_cmd = plant.CommandIndex(iface::kActuatorForce);
};

TEST(FaultInjectingHardware, MirrorsTheInnerInterfacesAndPassesReadingsThroughOutsideFaults) {
  Rig rig;
  FaultInjectingHardware f(
      rig.plant, {{std::string(iface::kTipPosition), false, FaultKind::kNaN, 1.0, 1.01, 0}});
  ASSERT_EQ(f.state_interfaces().size(), rig.plant.state_interfaces().size());
  for (std::size_t i = 0; i < f.state_interfaces().size(); ++i)
    EXPECT_EQ(f.state_interfaces()[i].name, rig.plant.state_interfaces()[i].name);
  f.Configure();
  f.Activate();
  EXPECT_EQ(rig.plant.lifecycle_state(), LifecycleState::kActive);
  const std::size_t tip = f.StateIndex(iface::kTipPosition);
  for (int k = 0; k < 1000; ++k) {
    f.set_command(rig.force_cmd, 2.0);
    f.read(k * 1e-3, 1e-3);
    EXPECT_EQ(f.state(tip), rig.plant.state(tip));
    f.write(k * 1e-3, 1e-3);
  }
  EXPECT_EQ(f.injected(), 0u);
}

TEST(FaultInjectingHardware, CorruptsReadingsInsideTheirWindowsAndCountsThem) {
  Rig rig;
  const std::string tip_name(iface::kTipPosition), base_name(iface::kBasePosition),
      force_name(iface::kSensorForce);
  FaultInjectingHardware f(rig.plant, {{tip_name, false, FaultKind::kDropout, 0.010, 0.020, 0},
                                       {base_name, false, FaultKind::kPosInf, 0.030, 0.031, 0},
                                       {force_name, false, FaultKind::kOffset, 0.040, 0.045, 3.0},
                                       {tip_name, false, FaultKind::kNaN, 0.050, 0.052, 0}});
  f.Configure();
  f.Activate();
  const std::size_t tip = f.StateIndex(iface::kTipPosition),
                    base = f.StateIndex(iface::kBasePosition),
                    force = f.StateIndex(iface::kSensorForce);
  double frozen = 0.0;
  for (int k = 0; k < 60; ++k) {
    const double t = k * 1e-3;
    f.set_command(rig.force_cmd, 5.0);  // the slide moves, so a frozen reading differs
    f.read(t, 1e-3);
    if (k == 9) frozen = f.state(tip);
    if (k >= 10 && k < 20) {
      EXPECT_EQ(f.state(tip), frozen) << k;
    }
    if (k == 30) {
      EXPECT_TRUE(std::isinf(f.state(base)) && f.state(base) > 0);
    }
    if (k != 30) {
      EXPECT_TRUE(std::isfinite(f.state(base))) << k;
    }
    if (k >= 40 && k < 45) {
      EXPECT_DOUBLE_EQ(f.state(force), rig.plant.state(force) + 3.0) << k;
    }
    if (k >= 50 && k < 52) {
      EXPECT_TRUE(std::isnan(f.state(tip))) << k;
    }
    if (k >= 52) {
      EXPECT_EQ(f.state(tip), rig.plant.state(tip)) << k;
    }
    f.write(t, 1e-3);
  }
  EXPECT_NE(frozen, rig.plant.state(tip));
  EXPECT_EQ(f.injected(), 10u + 1u + 5u + 2u);
}

TEST(FaultInjectingHardware, RejectsAFaultOnAnUnknownInterfaceOrAnInvertedWindow) {
  Rig rig;
  EXPECT_THROW(FaultInjectingHardware(rig.plant, {{"no/such", false, FaultKind::kNaN, 0, 1, 0}}),
               std::invalid_argument);
  EXPECT_THROW(FaultInjectingHardware(rig.plant, {{std::string(iface::kTipPosition), false,
                                                   FaultKind::kNaN, 1, 0, 0}}),
               std::invalid_argument);
}

TEST(FaultInjectingHardware, ASlowReadTakesItsTimeInsideTheWindowAndChangesNoReading) {
  Rig rig;
  const std::string base(iface::kBasePosition);
  FaultInjectingHardware f(rig.plant, {{base, false, FaultKind::kSlowRead, 0.010, 0.013, 2.0}});
  f.Configure();
  f.Activate();
  const std::size_t b = f.StateIndex(iface::kBasePosition);
  using Clock = std::chrono::steady_clock;
  double fastest_inside_ms = 1e9;
  int slow_outside = 0;  // reads outside the window that took 2 ms (a preempted test thread)
  for (int k = 0; k < 20; ++k) {
    f.set_command(rig.force_cmd, 2.0);
    const auto start = Clock::now();
    f.read(k * 1e-3, 1e-3);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    EXPECT_EQ(f.state(b), rig.plant.state(b));
    const bool inside = k >= 10 && k < 13;
    if (inside) fastest_inside_ms = std::min(fastest_inside_ms, ms);
    if (!inside && ms >= 2.0) ++slow_outside;
    f.write(k * 1e-3, 1e-3);
  }
  EXPECT_GE(fastest_inside_ms, 2.0);  // a busy wait of 2 ms cannot end sooner
  EXPECT_LE(slow_outside, 1);
  EXPECT_EQ(f.injected(), 3u);
  for (double ms : {0.0, -1.0, 1001.0, std::nan("")}) {
    EXPECT_THROW(FaultInjectingHardware(rig.plant, {{base, false, FaultKind::kSlowRead, 0, 1, ms}}),
                 std::invalid_argument)
        << ms;
  }
}

}  // namespace
}  // namespace echoservo::hw
