// The 1 kHz servo loop on the simulated catheter (the seed's model plant: Coulomb +
// viscous friction and the geometric deadzone), without backlash compensation: the
// base position loop alone, its safety behaviour, and the real-time runner.
#include "control/servo_loop.h"

#include <gtest/gtest.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <thread>
#include <vector>

#include "control/experiments/track_experiment.h"
#include "control/trajectory.h"
#include "hw/seed_plant.h"
#include "hw/simulated_catheter.h"
#include "tests/test_util/constants.h"

namespace echoservo::control {
namespace {

using testing::kNaN;

// A plant placed on the reference's start and activated, and a loop on it.
struct Rig {
  explicit Rig(const Trajectory& reference, ServoConfig config = {}, bool use_seed_config = true)
      : options(hw::SeedModelPlant(formats::CatheterConfig::SeedEvaluation())), plant(options) {
    plant.ResetTo(reference.Evaluate(0.0).position_mm);
    plant.Configure();
    plant.Activate();
    loop = std::make_unique<ServoLoop>(plant,
                                       use_seed_config ? SeedServoConfig(options, true) : config);
  }
  hw::PlantOptions options;
  hw::SimulatedCatheter plant;
  std::unique_ptr<ServoLoop> loop;
};

double RmsBaseError(const std::vector<CycleRecord>& records, double from_s, double to_s) {
  double sum = 0.0;
  int n = 0;
  for (const CycleRecord& r : records) {
    if (r.t_s < from_s || r.t_s > to_s) continue;
    const double e = r.reference_mm - r.base_mm;
    sum += e * e;
    ++n;
  }
  EXPECT_GT(n, 0);
  return std::sqrt(sum / n);
}

TEST(ServoLoopTest, RunFixedStepRecordsOneCyclePerMillisecond) {
  const SineTrajectory sine(5.0, 0.5);
  Rig rig(sine);
  NoCompensation none;
  const std::vector<CycleRecord> records = RunFixedStep(*rig.loop, sine, none, 1.0);
  ASSERT_EQ(records.size(), 1000u);
  for (std::size_t k = 0; k < records.size(); ++k) {
    const CycleRecord& r = records[k];
    ASSERT_EQ(r.t_s, static_cast<double>(k) * 1e-3);
    ASSERT_EQ(r.reference_mm, sine.Evaluate(r.t_s).position_mm);
    ASSERT_TRUE(std::isfinite(r.base_mm) && std::isfinite(r.tip_mm) && std::isfinite(r.force_n));
  }
  EXPECT_EQ(RunFixedStep(*rig.loop, sine, none, 0.25).size(), 250u);
}

TEST(ServoLoopTest, RunFixedStepRejectsInvalidDurations) {
  const SineTrajectory sine(5.0, 0.5);
  Rig rig(sine);
  NoCompensation none;
  for (double d : {0.0, -1.0, kNaN, 3600.5}) {
    EXPECT_THROW(RunFixedStep(*rig.loop, sine, none, d), std::invalid_argument) << d;
  }
}

// PID + friction/inertia feed-forward on a slow sine (5 mm, 0.5 Hz: 16 mm/s, 49 mm/s²):
// the base error is set by the encoder (1 µm), the force sensor/friction mismatch and
// stick-slip at reversals, well under 0.1 mm RMS.
TEST(ServoLoopTest, BaseFollowsASlowSine) {
  const SineTrajectory sine(5.0, 0.5);
  Rig rig(sine);
  NoCompensation none;
  const std::vector<CycleRecord> records = RunFixedStep(*rig.loop, sine, none, 4.0);
  EXPECT_LT(RmsBaseError(records, 0.5, 4.0), 0.1);
  EXPECT_EQ(rig.loop->limiter().faults(), 0u);
}

// A ±15 mm square wave with a stiff position loop (kp = 500 N/mm: a 0.1 mm error
// already asks for 50 N) drives the loop into force saturation; the commanded force
// never leaves ±max_force.
class SquareWave final : public Trajectory {
 public:
  MotionSample Evaluate(double t) const override {
    return {std::fmod(t, 0.5) < 0.25 ? 15.0 : -15.0, 0.0, 0.0};
  }
  std::string name() const override { return "square"; }
};

TEST(ServoLoopTest, NeverCommandsAForceBeyondTheLimit) {
  const SquareWave square;
  const hw::PlantOptions options = hw::SeedModelPlant(formats::CatheterConfig::SeedEvaluation());
  const ServoConfig seed = SeedServoConfig(options, true);
  for (double pid_limit_factor : {1.0, 4.0}) {
    // Factor 4: the PID may ask for more than the limiter allows; the limiter clamps
    // and counts each clamp as a force fault.
    ServoConfig config = seed;
    config.pid.kp_n_per_mm = params::kKpNPerMm.max;  // the stiffest gain a catheter may have
    config.pid.output_limit_n = pid_limit_factor * config.limits.max_force_n;
    Rig rig(square, config, false);
    NoCompensation none;
    const std::vector<CycleRecord> records = RunFixedStep(*rig.loop, square, none, 2.0);
    double peak = 0.0;
    for (const CycleRecord& r : records) {
      ASSERT_LE(std::abs(r.actuator_force_n), config.limits.max_force_n) << "t=" << r.t_s;
      peak = std::max(peak, std::abs(r.actuator_force_n));
    }
    EXPECT_EQ(peak, config.limits.max_force_n);  // the test did drive it into saturation
    if (pid_limit_factor > 1.0) {
      EXPECT_GT(rig.loop->limiter().count(LimitEvent::kForce), 0u);
    } else {
      EXPECT_EQ(rig.loop->limiter().count(LimitEvent::kForce), 0u);
    }
  }
}

// A slow sine that goes NaN for t in [0.5, 0.6] s (a lost estimator, a bad file).
class GlitchySine final : public Trajectory {
 public:
  MotionSample Evaluate(double t) const override {
    if (t >= 0.5 && t <= 0.6) return {kNaN, kNaN, kNaN};
    return sine_.Evaluate(t);
  }
  std::string name() const override { return "glitchy"; }

 private:
  SineTrajectory sine_{5.0, 0.5};
};

TEST(ServoLoopTest, NonFiniteReferenceIsAFaultAndTrackingResumes) {
  const GlitchySine glitchy;
  Rig rig(glitchy);
  NoCompensation none;
  const std::vector<CycleRecord> records = RunFixedStep(*rig.loop, glitchy, none, 3.0);
  std::uint64_t nan_cycles = 0;
  const Limits& limits = rig.loop->config().limits;
  for (const CycleRecord& r : records) {
    if (std::isnan(r.reference_mm)) ++nan_cycles;
    ASSERT_GE(r.base_mm, limits.travel_min_mm) << r.t_s;
    ASSERT_LE(r.base_mm, limits.travel_max_mm) << r.t_s;
    ASSERT_TRUE(std::isfinite(r.base_cmd_mm)) << r.t_s;
    ASSERT_TRUE(std::isfinite(r.actuator_force_n)) << r.t_s;
    ASSERT_LE(std::abs(r.actuator_force_n), limits.max_force_n);
  }
  EXPECT_GE(nan_cycles, 100u);
  EXPECT_LE(nan_cycles, 101u);
  EXPECT_EQ(rig.loop->limiter().count(LimitEvent::kNonFinite), nan_cycles);
  EXPECT_EQ(rig.loop->limiter().faults(), nan_cycles);
  // During the glitch the setpoint is held where it was when the reference vanished.
  double held = kNaN;
  for (const CycleRecord& r : records) {
    if (!std::isnan(r.reference_mm)) continue;
    if (std::isnan(held)) held = r.base_cmd_mm;
    // Braking from ≤ 16 mm/s at a_max covers ≤ v²/(2a) + v·dt ≈ 0.018 mm.
    EXPECT_NEAR(r.base_cmd_mm, held, 0.02) << r.t_s;
  }
  // Before and after: normal tracking.
  EXPECT_LT(RmsBaseError(records, 0.1, 0.499), 0.1);
  EXPECT_LT(RmsBaseError(records, 1.0, 3.0), 0.1);
}

// Counts compensator calls (one per cycle) across threads.
class CountingCompensator final : public BacklashCompensator {
 public:
  std::string name() const override { return "counting"; }
  std::atomic<std::uint64_t> calls{0};

 protected:
  BaseCommand DoCalc(const CompensatorInput& in) override {
    calls.fetch_add(1);
    return none_.Calc(in);
  }

 private:
  NoCompensation none_;
};

TEST(ServoLoopTest, ConfigValidation) {
  const SineTrajectory sine(5.0, 0.5);
  const hw::PlantOptions options = hw::SeedModelPlant(formats::CatheterConfig::SeedEvaluation());
  hw::SimulatedCatheter plant(options);
  plant.Configure();
  plant.Activate();
  for (double period : {0.0, 1e-6, 0.2, kNaN}) {
    ServoConfig c;
    c.period_s = period;
    EXPECT_THROW(ServoLoop(plant, c), std::invalid_argument) << period;
  }
  ServoConfig c;
  c.pid.kp_n_per_mm = -1.0;
  EXPECT_THROW(ServoLoop(plant, c), std::invalid_argument);
  c = ServoConfig{};
  c.limits.max_force_n = 0.0;
  EXPECT_THROW(ServoLoop(plant, c), std::invalid_argument);
  c = ServoConfig{};
  c.feedforward.coulomb_n = -0.1;
  EXPECT_THROW(ServoLoop(plant, c), std::invalid_argument);
  EXPECT_NO_THROW(ServoLoop(plant, ServoConfig{}));
}

}  // namespace
}  // namespace echoservo::control
