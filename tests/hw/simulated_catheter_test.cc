// The simulated catheter as a plant: lifecycle and interfaces, the actuator, the
// sensors, and each transmission effect as it shows in closed-loop measured data.
//
// Tolerances come from the sensor model (hw/simulated_catheter.h, SensorParams): the
// force sensor has σ_F = 0.0075 N noise and a 0.002 N quantum, the tip sensor σ_tip =
// 0.03 mm and a 0.0125 mm quantum, the base encoder a 0.001 mm quantum. The mean of n
// noisy samples has a standard deviation σ/√n; we allow 4 of those (a false alarm
// about once in 16 000 runs, and the seed is fixed) plus half a quantum (the largest
// bias rounding could add; with σ > q the bias is in fact far smaller).
#include "hw/simulated_catheter.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/test_util/constants.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::hw {
namespace {

using ::echoservo::testing::ExpectContains;
using ::echoservo::testing::InvalidArgumentMessage;

using testing::kDt;

// One control cycle as the controller saw it: the sensors read at t, the force
// commanded for [t, t + dt), and the ground truth at the moment of the read.
struct Sample {
  double t = 0.0;
  double base = 0.0;      // measured, mm
  double velocity = 0.0;  // mm/s
  double sensor = 0.0;    // force sensor, N
  double actuator = 0.0;  // actuator force (state), N
  double tip = 0.0;       // measured, mm
  double faults = 0.0;
  double command = 0.0;  // N
  PlantTruth truth;
};

// A reference trajectory: position (mm) and velocity (mm/s) at time t.
struct Reference {
  std::function<double(double)> position;
  std::function<double(double)> velocity;
};

Reference Ramp(double x0, double v) {
  return {[=](double t) { return x0 + v * t; }, [=](double) { return v; }};
}

// A triangle wave about 0 with the given amplitude and speed, starting at -amplitude
// going up.
Reference Triangle(double amplitude, double speed) {
  const double half_period = 2.0 * amplitude / speed;
  auto phase = [=](double t) { return std::fmod(t, 2.0 * half_period); };
  return {[=](double t) {
            const double p = phase(t);
            return p < half_period ? -amplitude + speed * p : amplitude - speed * (p - half_period);
          },
          [=](double t) { return phase(t) < half_period ? speed : -speed; }};
}

// Drives a SimulatedCatheter through configure/activate and 1 ms cycles.
class CatheterRig {
 public:
  explicit CatheterRig(PlantOptions options, double start_mm = 0.0, double dt = kDt)
      : plant_(std::move(options)), dt_(dt) {
    plant_.ResetTo(start_mm);
    plant_.Configure();
    plant_.Activate();
    s_base_ = plant_.StateIndex(iface::kBasePosition);
    s_vel_ = plant_.StateIndex(iface::kBaseVelocity);
    s_sensor_ = plant_.StateIndex(iface::kSensorForce);
    s_actuator_ = plant_.StateIndex(iface::kActuatorForce);
    s_tip_ = plant_.StateIndex(iface::kTipPosition);
    s_fault_ = plant_.StateIndex(iface::kFaultCount);
    c_force_ = plant_.CommandIndex(iface::kActuatorForce);
  }

  SimulatedCatheter& plant() { return plant_; }
  const TransmissionModel& model() const { return plant_.model(); }

  // One cycle with the force chosen by `law` from what was just read.
  Sample Cycle(const std::function<double(const Sample&)>& law) {
    Sample s;
    s.t = t_;
    s.truth = plant_.truth();
    plant_.read(t_, dt_);
    s.base = plant_.state(s_base_);
    s.velocity = plant_.state(s_vel_);
    s.sensor = plant_.state(s_sensor_);
    s.actuator = plant_.state(s_actuator_);
    s.tip = plant_.state(s_tip_);
    s.faults = plant_.state(s_fault_);
    s.command = law(s);
    plant_.set_command(c_force_, s.command);
    plant_.write(t_, dt_);
    t_ += dt_;
    return s;
  }

  std::vector<Sample> ConstantForce(double force_n, double duration_s) {
    return Run([=](const Sample&) { return force_n; }, duration_s);
  }

  // A stiff PD position loop on the true base position and velocity: kp = 10 N/mm
  // (ω = √(kp/m) = 200 rad/s) and kd = 0.2 N/(mm/s) (ζ ≈ 2, enough damping to
  // dominate a Stribeck curve's negative slope, ≤ 0.12 N/(mm/s) here).
  std::vector<Sample> Track(const Reference& ref, double duration_s, double kp = 10.0,
                            double kd = 0.2) {
    const double t0 = t_;
    return Run(
        [&, t0](const Sample& s) {
          const double t = s.t - t0;
          return kp * (ref.position(t) - s.truth.base_mm) +
                 kd * (ref.velocity(t) - s.truth.base_velocity_mm_s);
        },
        duration_s);
  }

  std::vector<Sample> Run(const std::function<double(const Sample&)>& law, double duration_s) {
    std::vector<Sample> out;
    const auto n = static_cast<std::size_t>(std::llround(duration_s / dt_));
    out.reserve(n);
    for (std::size_t i = 0; i < n; ++i) out.push_back(Cycle(law));
    return out;
  }

 private:
  SimulatedCatheter plant_;
  double dt_;
  double t_ = 0.0;
  std::size_t s_base_, s_vel_, s_sensor_, s_actuator_, s_tip_, s_fault_, c_force_;
};

PlantOptions Options(std::vector<std::string> effects = {"coulomb_friction", "viscous_friction",
                                                         "backlash"}) {
  PlantOptions o;
  o.effects = std::move(effects);
  return o;
}

PlantOptions Noiseless(PlantOptions o) {
  o.sensor_noise = false;
  o.sensors.tip_quantum_mm = 0.0;
  o.sensors.force_quantum_n = 0.0;
  o.sensors.base_quantum_mm = 0.0;
  return o;
}

double MeanOf(const std::vector<double>& x) {
  return std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(x.size());
}

double SampleStd(const std::vector<double>& x) {
  const double m = MeanOf(x);
  double ss = 0.0;
  for (double v : x) ss += (v - m) * (v - m);
  return std::sqrt(ss / static_cast<double>(x.size() - 1));
}

template <class F>
std::vector<double> Collect(const std::vector<Sample>& samples, F&& f) {
  std::vector<double> out;
  for (const Sample& s : samples) out.push_back(f(s));
  return out;
}

std::vector<Sample> After(const std::vector<Sample>& samples, double t_s) {
  std::vector<Sample> out;
  for (const Sample& s : samples) {
    if (s.t >= t_s) out.push_back(s);
  }
  return out;
}

const SensorParams kRigSensors{};
// Budget for the mean of n force-sensor samples.
double ForceMeanTolerance(std::size_t n) {
  return 4.0 * kRigSensors.force_noise_n / std::sqrt(static_cast<double>(n)) +
         0.5 * kRigSensors.force_quantum_n;
}

// ----------------------------------------------------------------- lifecycle and API

TEST(SimulatedCatheter, StandardInterfaces) {
  SimulatedCatheter plant(Options());
  const std::vector<std::pair<std::string, std::string>> states = {
      {"base/position", "mm"}, {"base/velocity", "mm/s"},   {"actuator/current", "A"},
      {"actuator/force", "N"}, {"force_sensor/force", "N"}, {"tip/position", "mm"},
      {"fault/count", "1"}};
  ASSERT_EQ(plant.state_interfaces().size(), states.size());
  for (std::size_t i = 0; i < states.size(); ++i) {
    EXPECT_EQ(plant.state_interfaces()[i].name, states[i].first);
    EXPECT_EQ(plant.state_interfaces()[i].unit, states[i].second);
    EXPECT_EQ(plant.StateIndex(states[i].first), i);
  }
  EXPECT_EQ(std::string(iface::kTipPosition), "tip/position");
  ASSERT_EQ(plant.command_interfaces().size(), 1u);
  EXPECT_EQ(plant.command_interfaces()[0].name, iface::kActuatorForce);
  EXPECT_EQ(plant.command_interfaces()[0].unit, "N");
  EXPECT_EQ(plant.CommandIndex(iface::kActuatorForce), 0u);
  EXPECT_THROW(plant.StateIndex("tip/velocity"), std::invalid_argument);
  EXPECT_THROW(plant.CommandIndex("base/position"), std::invalid_argument);
}

TEST(SimulatedCatheter, LifecycleTransitions) {
  SimulatedCatheter plant(Options());
  EXPECT_EQ(plant.lifecycle_state(), LifecycleState::kUnconfigured);
  EXPECT_THROW(plant.read(0.0, kDt), std::logic_error);
  EXPECT_THROW(plant.write(0.0, kDt), std::logic_error);
  EXPECT_THROW(plant.Activate(), std::logic_error);
  EXPECT_THROW(plant.Deactivate(), std::logic_error);
  EXPECT_THROW(plant.Cleanup(), std::logic_error);

  plant.Configure();
  EXPECT_EQ(plant.lifecycle_state(), LifecycleState::kInactive);
  EXPECT_THROW(plant.read(0.0, kDt), std::logic_error);  // configured is not active
  EXPECT_THROW(plant.write(0.0, kDt), std::logic_error);
  EXPECT_THROW(plant.Configure(), std::logic_error);
  EXPECT_THROW(plant.Deactivate(), std::logic_error);

  plant.Activate();
  EXPECT_EQ(plant.lifecycle_state(), LifecycleState::kActive);
  EXPECT_NO_THROW(plant.read(0.0, kDt));
  EXPECT_NO_THROW(plant.write(0.0, kDt));
  EXPECT_THROW(plant.write(0.0, 0.0), std::invalid_argument);
  EXPECT_THROW(plant.write(0.0, std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  EXPECT_THROW(plant.Activate(), std::logic_error);
  EXPECT_THROW(plant.Configure(), std::logic_error);
  EXPECT_THROW(plant.Cleanup(), std::logic_error);

  plant.Deactivate();
  EXPECT_EQ(plant.lifecycle_state(), LifecycleState::kInactive);
  EXPECT_THROW(plant.read(0.0, kDt), std::logic_error);
  plant.Cleanup();
  EXPECT_EQ(plant.lifecycle_state(), LifecycleState::kUnconfigured);
  EXPECT_THROW(plant.write(0.0, kDt), std::logic_error);
  plant.Configure();  // the cycle can start again
  plant.Activate();
  EXPECT_NO_THROW(plant.read(0.0, kDt));
}

TEST(SimulatedCatheter, ActivateZeroesTheCommand) {
  SimulatedCatheter plant(Options());
  plant.Configure();
  plant.set_command(0, 5.0);
  plant.Activate();
  EXPECT_EQ(plant.command(0), 0.0);
}

TEST(SimulatedCatheter, InvalidOptionsThrowNamingTheField) {
  auto expect_field = [](PlantOptions o, const std::string& field) {
    const std::string msg = InvalidArgumentMessage([&] { SimulatedCatheter p(std::move(o)); });
    EXPECT_NE(msg.find(field), std::string::npos) << "'" << msg << "' lacks '" << field << "'";
  };
  PlantOptions o = Options();
  o.actuator.moving_mass_kg = -0.25;
  expect_field(o, "actuator.moving_mass_kg");
  o = Options();
  o.actuator.moving_mass_kg = 0.0;
  expect_field(o, "actuator.moving_mass_kg");
  o = Options();
  o.substeps = 0;
  expect_field(o, "substeps");
  o = Options();
  o.substeps = -3;
  expect_field(o, "substeps");
  o = Options();
  o.actuator.current_limit_a = std::numeric_limits<double>::quiet_NaN();
  expect_field(o, "actuator.current_limit_a");
  o = Options();
  o.actuator.force_constant_n_per_a = 0.0;
  expect_field(o, "actuator.force_constant_n_per_a");
  o = Options();
  o.actuator.current_time_constant_s = -1e-4;
  expect_field(o, "actuator.current_time_constant_s");
  o = Options();
  o.actuator.travel_mm = std::numeric_limits<double>::infinity();
  expect_field(o, "actuator.travel_mm");
  o = Options();
  o.actuator.end_stop_stiffness_n_per_mm = -1.0;
  expect_field(o, "actuator.end_stop_stiffness_n_per_mm");
  o = Options();
  o.sensors.tip_noise_mm = -0.03;
  expect_field(o, "sensors.tip_noise_mm");
  o = Options();
  o.sensors.force_quantum_n = std::numeric_limits<double>::quiet_NaN();
  expect_field(o, "sensors.force_quantum_n");
  // The transmission: geometry, effects and parameters.
  o = Options();
  o.config.guidewire_od_mm = 1.8;
  expect_field(o, "guidewire_od_mm");
  expect_field(Options({"coulomb_friction", "slippery"}), "slippery");
  o = Options();
  o.parameters = {{"viscous_friction.b_n_per_mm_s", -1.0}};
  expect_field(o, "viscous_friction.b_n_per_mm_s");
  o = Options();
  o.parameters = {{"capstan_friction.mu", 0.2}};  // not in the seed model
  expect_field(o, "capstan_friction.mu");
  // Zero noise and zero quanta are valid (an ideal sensor).
  EXPECT_NO_THROW(SimulatedCatheter p(Noiseless(Options())));
}

TEST(SimulatedCatheter, ParametersApplyOverDefaults) {
  PlantOptions o = Options();
  o.parameters = {{"coulomb_friction.f0_n", 2.5}, {"viscous_friction.b_n_per_mm_s", 0.01}};
  SimulatedCatheter plant(o);
  EXPECT_EQ(plant.model().GetParameter("coulomb_friction.f0_n"), 2.5);
  EXPECT_EQ(plant.model().GetParameter("viscous_friction.b_n_per_mm_s"), 0.01);
  EXPECT_EQ(plant.model().effect_names(), o.effects);
}

TEST(SimulatedCatheter, ResetPutsTheTipAtTheDeadzoneCentre) {
  CatheterRig rig(Noiseless(Options()), 0.0);
  const double half = 0.5 * rig.model().BacklashWidthMm();
  ASSERT_GT(half, 1.0);
  rig.plant().ResetTo(5.0);
  const PlantTruth& t = rig.plant().truth();
  EXPECT_EQ(t.base_mm, 5.0);
  EXPECT_EQ(t.drive_mm, 5.0);
  EXPECT_EQ(t.tip_mm, 5.0);
  EXPECT_EQ(t.base_velocity_mm_s, 0.0);
  EXPECT_TRUE(t.stuck);
  // Centred means the base can travel half the width either way before the tip moves.
  auto settle_at = [&](double x) {
    rig.Track({[=](double) { return x; }, [](double) { return 0.0; }}, 0.3);
    return rig.plant().truth();
  };
  for (double x : {5.0 + 0.9 * half, 5.0 - 0.9 * half}) {
    const PlantTruth s = settle_at(x);
    EXPECT_NEAR(s.base_mm, x, 0.15);  // PD with Coulomb friction stops within F/kp = 0.1 mm
    EXPECT_EQ(s.tip_mm, 5.0) << "base at " << x;
  }
  const PlantTruth s = settle_at(5.0 + half + 1.0);
  EXPECT_NEAR(s.tip_mm, s.base_mm - half, 1e-9);  // engaged: on the lower band edge
  EXPECT_GT(s.tip_mm, 5.5);
  // The measured tip shows it too (ideal sensor).
  const Sample m = rig.Cycle([](const Sample&) { return 0.0; });
  EXPECT_NEAR(m.tip, m.truth.tip_mm, 1e-12);

  EXPECT_THROW(rig.plant().ResetTo(30.0), std::invalid_argument);  // outside ±25.4 mm
  EXPECT_THROW(rig.plant().ResetTo(std::numeric_limits<double>::quiet_NaN()),
               std::invalid_argument);
}

// ------------------------------------------------------------------------- actuator

TEST(SimulatedCatheter, CurrentLimitCapsTheActuatorForce) {
  const ActuatorParams a;
  ASSERT_NEAR(a.PeakForceN(), 26.7, 1e-9);
  for (double cmd : {100.0, -1e6}) {
    CatheterRig rig(Options(), cmd > 0 ? -20.0 : 20.0);
    const std::vector<Sample> s = rig.ConstantForce(cmd, 0.012);
    double peak = 0.0;
    for (const Sample& x : s) peak = std::max(peak, std::abs(x.actuator));
    EXPECT_LE(peak, a.PeakForceN() * (1.0 + 1e-12));
    // After 10 ms ≫ τ_current = 0.3 ms the current sits at the limit.
    EXPECT_NEAR(std::abs(s.back().actuator), a.PeakForceN(), 1e-6);
    EXPECT_NEAR(s.back().actuator / a.force_constant_n_per_a,
                rig.plant().state(iface::kActuatorCurrent), 1e-12);
    // And the slide accelerates as the capped force (not the command) dictates:
    // m dv/dt = F_peak − f0 − b v, v(t) = v∞ (1 − exp(−t/τm)), v∞ = (F_peak − f0)/b,
    // τm = m/b. The first-order current loop delays the force by at most τ_current.
    const double f0 = rig.model().GetParameter("coulomb_friction.f0_n");
    const double b = rig.model().GetParameter("viscous_friction.b_n_per_mm_s");
    const double m = a.moving_mass_kg / 1000.0;  // N per mm/s²
    const double v_inf = (a.PeakForceN() - f0) / b;
    auto v_ode = [&](double t) { return v_inf * (1.0 - std::exp(-t * b / m)); };
    const double t_end = s.back().t + kDt;
    const double v = std::abs(rig.plant().truth().base_velocity_mm_s);
    const double slack = (a.PeakForceN() / m) * 1e-4;  // one 0.1 ms substep of acceleration
    EXPECT_LE(v, v_ode(t_end) + slack);
    EXPECT_GE(v, v_ode(t_end - a.current_time_constant_s) - slack);
  }
}

TEST(SimulatedCatheter, NonFiniteCommandGivesZeroForceAndCountsAFault) {
  CatheterRig rig(Options());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  double expected_faults = 0.0;
  for (double bad : {nan, inf, -inf}) {
    const Sample s = rig.Cycle([=](const Sample&) { return bad; });
    EXPECT_EQ(s.faults, expected_faults);
    ++expected_faults;
    const Sample after = rig.Cycle([](const Sample&) { return 0.0; });
    EXPECT_EQ(after.faults, expected_faults);
    EXPECT_EQ(after.actuator, 0.0);
    EXPECT_EQ(after.truth.base_velocity_mm_s, 0.0);
    EXPECT_EQ(after.truth.base_mm, 0.0);
  }
  // A non-finite command while pushing: the amplifier treats it as 0, the current decays
  // with τ = 0.3 ms, and the count goes on.
  rig.ConstantForce(10.0, 0.005);
  EXPECT_NEAR(rig.plant().state(iface::kActuatorForce), 10.0, 1e-3);
  rig.ConstantForce(nan, 0.005);
  rig.plant().read(0.0, kDt);
  EXPECT_LT(std::abs(rig.plant().state(iface::kActuatorForce)), 10.0 * std::exp(-4e-3 / 3e-4));
  EXPECT_EQ(rig.plant().state(iface::kFaultCount), expected_faults + 5.0);
  // A finite command does not count.
  rig.ConstantForce(0.5, 0.003);
  rig.plant().read(0.0, kDt);
  EXPECT_EQ(rig.plant().state(iface::kFaultCount), expected_faults + 5.0);
}

TEST(SimulatedCatheter, StickSlipAtTheBreakawayLevel) {
  for (const auto& effects :
       {std::vector<std::string>{"coulomb_friction", "viscous_friction", "backlash"},
        std::vector<std::string>{"coulomb_friction", "viscous_friction", "stribeck_friction",
                                 "backlash"}}) {
    for (double sign : {1.0, -1.0}) {
      const double level = CatheterRig(Options(effects)).model().FrictionLevelN();
      // Below breakaway: static friction balances the force, the base does not move, and
      // the force sensor reads the applied force.
      {
        CatheterRig rig(Noiseless(Options(effects)));
        const std::vector<Sample> s = rig.ConstantForce(sign * 0.95 * level, 0.2);
        EXPECT_EQ(rig.plant().truth().base_mm, 0.0);
        EXPECT_EQ(rig.plant().truth().base_velocity_mm_s, 0.0);
        EXPECT_TRUE(rig.plant().truth().stuck);
        EXPECT_NEAR(s.back().sensor, sign * 0.95 * level, 1e-9);
      }
      // Above it the base breaks away and accelerates in the direction of the force.
      {
        CatheterRig rig(Noiseless(Options(effects)));
        const std::vector<Sample> s = rig.ConstantForce(sign * 1.05 * level, 0.2);
        const PlantTruth& t = rig.plant().truth();
        EXPECT_FALSE(t.stuck);
        EXPECT_GT(sign * t.base_velocity_mm_s, 0.0);
        EXPECT_GT(sign * t.base_mm, 0.0);
        // Speeding up: the velocity rises over the run.
        EXPECT_GT(sign * s.back().truth.base_velocity_mm_s,
                  sign * s[s.size() / 2].truth.base_velocity_mm_s);
      }
    }
  }
  // With Stribeck friction a force between the dynamic and the static level holds the
  // base at rest, although it would keep an already sliding base moving.
  CatheterRig rig(Noiseless(Options({"coulomb_friction", "stribeck_friction", "backlash"})));
  const double f0 = rig.model().GetParameter("coulomb_friction.f0_n");
  const double level = rig.model().FrictionLevelN();
  ASSERT_GT(level, f0 + 0.2);
  rig.ConstantForce(0.5 * (f0 + level), 0.2);
  EXPECT_EQ(rig.plant().truth().base_mm, 0.0);
}

TEST(SimulatedCatheter, BreakawayAccelerationFollowsNewton) {
  // Seed friction, F = 1.1 × f0: m dv/dt = F − f0 − b v.
  CatheterRig rig(Noiseless(Options()));
  const double f0 = rig.model().GetParameter("coulomb_friction.f0_n");
  const double b = rig.model().GetParameter("viscous_friction.b_n_per_mm_s");
  const double m = ActuatorParams{}.moving_mass_kg / 1000.0;
  const double force = 1.1 * f0;
  rig.ConstantForce(force, 0.1);
  const double v_inf = (force - f0) / b;
  auto v_ode = [&](double t) { return v_inf * (1.0 - std::exp(-t * b / m)); };
  const double v = rig.plant().truth().base_velocity_mm_s;
  const double slack = ((force - f0) / m) * 1e-4;
  EXPECT_LE(v, v_ode(0.1) + slack);
  EXPECT_GE(v, v_ode(0.1 - ActuatorParams{}.current_time_constant_s) - slack);
}

TEST(SimulatedCatheter, CoastsToAStopAndSticks) {
  // Push, then command zero: the slide decelerates under m dv/dt = −(f0 + b v), stops
  // after a coasting distance x(v0) = (m/b) (v0 − (f0/b) ln(1 + b v0/f0)) and then stays
  // stuck (static friction holds it; no chatter about v = 0). The decaying coil current
  // adds at most an impulse F τ_current at the start, which bounds x from above.
  CatheterRig rig(Noiseless(Options()), -20.0);
  const double f0 = rig.model().GetParameter("coulomb_friction.f0_n");
  const double b = rig.model().GetParameter("viscous_friction.b_n_per_mm_s");
  const ActuatorParams a;
  const double m = a.moving_mass_kg / 1000.0;
  const double push = 3.0;
  rig.ConstantForce(push, 0.03);
  const PlantTruth released = rig.plant().truth();
  ASSERT_GT(released.base_velocity_mm_s, 100.0);
  const std::vector<Sample> s = rig.ConstantForce(0.0, 0.3);
  auto coast = [&](double v0) { return (m / b) * (v0 - (f0 / b) * std::log(1.0 + b * v0 / f0)); };
  const double x = rig.plant().truth().base_mm - released.base_mm;
  const double slack = 1e-4 * released.base_velocity_mm_s;  // one 0.1 ms substep of travel
  EXPECT_GE(x, coast(released.base_velocity_mm_s) - slack);
  EXPECT_LE(x, coast(released.base_velocity_mm_s + push * a.current_time_constant_s / m) + slack);
  // Stop time t = (m/b) ln(1 + b v0/f0) ≈ 37 ms; from 0.1 s on the slide is at rest.
  const std::vector<Sample> rest = After(s, s.front().t + 0.1);
  for (const Sample& r : rest) {
    ASSERT_EQ(r.truth.base_velocity_mm_s, 0.0);
    ASSERT_EQ(r.truth.base_mm, rest.front().truth.base_mm);
    ASSERT_TRUE(r.truth.stuck);
  }
}

TEST(SimulatedCatheter, EndStopsHoldTheBaseAtFullForce) {
  // From rest at the centre at full force, the slide hits a stop at speed. With no
  // friction, energy gives the deepest overshoot x into the stop spring k:
  //   F (d + x) = k x²/2  →  x = (F + √(F² + 2 k F d)) / k,   d = travel/2.
  // Friction only lowers it. Afterwards the slide must stay inside travel/2 + x.
  const ActuatorParams a;
  const double half = 0.5 * a.travel_mm;
  const double F = a.PeakForceN();
  const double k = a.end_stop_stiffness_n_per_mm;
  const double x_max = (F + std::sqrt(F * F + 2.0 * k * F * half)) / k;
  ASSERT_LT(x_max, 3.0);  // "small": a few mm against 50.8 mm of travel
  for (double sign : {1.0, -1.0}) {
    CatheterRig rig(Options(), 0.0);
    const std::vector<Sample> s = rig.ConstantForce(sign * 1000.0, 1.5);
    double deepest = 0.0;
    for (const Sample& x : s) deepest = std::max(deepest, sign * x.truth.base_mm);
    EXPECT_GT(deepest, half) << "the slide must reach the stop";
    EXPECT_LE(deepest, half + x_max);
    // Friction bleeds the bouncing off; it comes to rest (stuck) pressed into the stop
    // where static friction makes up the difference between coil and spring:
    // |F − k x| ≤ f0, x ∈ [(F − f0)/k, (F + f0)/k].
    const double f0 = rig.model().GetParameter("coulomb_friction.f0_n");
    const PlantTruth& end = rig.plant().truth();
    EXPECT_TRUE(end.stuck);
    const double x_end = sign * end.base_mm - half;
    EXPECT_GE(x_end, (F - f0) / k - 1e-9);
    EXPECT_LE(x_end, (F + f0) / k + 1e-9);
  }
}

// -------------------------------------------------------------------------- sensors

TEST(SimulatedCatheter, SensorNoiseHasTheSpecifiedSigma) {
  // At rest with no force: the true force is 0 and the true tip is constant, so the
  // readings are pure noise. Rounding to a quantum q adds q²/12 of variance.
  CatheterRig rig(Options());
  const std::vector<Sample> s = rig.ConstantForce(0.0, 4.0);
  ASSERT_GE(s.size(), 2000u);
  const std::vector<double> force = Collect(s, [](const Sample& x) { return x.sensor; });
  const std::vector<double> tip = Collect(s, [](const Sample& x) { return x.tip; });
  const double sf =
      std::hypot(kRigSensors.force_noise_n, kRigSensors.force_quantum_n / std::sqrt(12.0));
  const double st =
      std::hypot(kRigSensors.tip_noise_mm, kRigSensors.tip_quantum_mm / std::sqrt(12.0));
  EXPECT_NEAR(SampleStd(force), sf, 0.15 * sf);
  EXPECT_NEAR(SampleStd(tip), st, 0.15 * st);
  // Unbiased, too.
  EXPECT_NEAR(MeanOf(force), 0.0, ForceMeanTolerance(force.size()));
  EXPECT_NEAR(MeanOf(tip), 0.0,
              4.0 * kRigSensors.tip_noise_mm / std::sqrt(static_cast<double>(tip.size())) +
                  0.5 * kRigSensors.tip_quantum_mm);
  // Readings sit on the quantisation grid.
  for (std::size_t i = 0; i < 50; ++i) {
    EXPECT_NEAR(std::remainder(force[i], kRigSensors.force_quantum_n), 0.0, 1e-12);
    EXPECT_NEAR(std::remainder(tip[i], kRigSensors.tip_quantum_mm), 0.0, 1e-12);
  }
  // Force and tip noise are independent.
  double cov = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i)
    cov += (force[i] - MeanOf(force)) * (tip[i] - MeanOf(tip));
  const double corr = cov / static_cast<double>(s.size() - 1) / (SampleStd(force) * SampleStd(tip));
  EXPECT_LT(std::abs(corr), 4.0 / std::sqrt(static_cast<double>(s.size())));
}

TEST(SimulatedCatheter, NoiseCanBeSwitchedOff) {
  PlantOptions o = Options();
  o.sensor_noise = false;
  CatheterRig rig(o, 1.23456);
  const std::vector<Sample> s = rig.Track(Ramp(1.23456, 8.0), 0.5);
  for (const Sample& x : s) {
    // Only the quantisation is left.
    EXPECT_NEAR(
        x.base,
        kRigSensors.base_quantum_mm * std::round(x.truth.base_mm / kRigSensors.base_quantum_mm),
        1e-12);
    EXPECT_NEAR(
        x.tip, kRigSensors.tip_quantum_mm * std::round(x.truth.tip_mm / kRigSensors.tip_quantum_mm),
        1e-12);
    EXPECT_NEAR(x.sensor,
                kRigSensors.force_quantum_n *
                    std::round(x.truth.friction_force_n / kRigSensors.force_quantum_n),
                1e-12);
    EXPECT_EQ(x.velocity, x.truth.base_velocity_mm_s);
  }
  // Two noiseless plants agree exactly whatever their seeds.
  PlantOptions o2 = o;
  o2.seed = 99;
  CatheterRig a(o, 0.0), b(o2, 0.0);
  const std::vector<Sample> sa = a.Track(Ramp(0.0, 5.0), 0.2);
  const std::vector<Sample> sb = b.Track(Ramp(0.0, 5.0), 0.2);
  for (std::size_t i = 0; i < sa.size(); ++i) {
    ASSERT_EQ(sa[i].tip, sb[i].tip);
    ASSERT_EQ(sa[i].sensor, sb[i].sensor);
  }
}

TEST(SimulatedCatheter, SameSeedSameNoise) {
  CatheterRig a(Options()), b(Options());
  PlantOptions o = Options();
  o.seed = 2;
  CatheterRig c(o);
  const auto sa = a.ConstantForce(0.0, 0.1);
  const auto sb = b.ConstantForce(0.0, 0.1);
  const auto sc = c.ConstantForce(0.0, 0.1);
  bool differs = false;
  for (std::size_t i = 0; i < sa.size(); ++i) {
    ASSERT_EQ(sa[i].sensor, sb[i].sensor);
    ASSERT_EQ(sa[i].tip, sb[i].tip);
    differs = differs || sa[i].sensor != sc[i].sensor;
  }
  EXPECT_TRUE(differs);
}

TEST(SimulatedCatheter, SensorDelayShiftsTheMeasuredTip) {
  // Ideal sensor; the measured tip at t is the true tip at t − d.
  for (double delay : {0.005, 0.0123}) {
    PlantOptions o =
        Noiseless(Options({"coulomb_friction", "viscous_friction", "backlash", "sensor_delay"}));
    o.parameters = {{"sensor_delay.delay_s", delay}};
    CatheterRig rig(o, -10.0);
    const std::vector<Sample> s = rig.Track(Triangle(10.0, 20.0), 2.0);
    const double lag_cycles = delay / kDt;
    double worst = 0.0;
    double moved = 0.0;
    std::size_t checked = 0;
    for (std::size_t i = 100; i < s.size(); ++i) {
      // Truth between cycle records: read linearly where the true tip moves at a
      // constant rate over the records around it (not at a reversal or an engagement,
      // where it bends inside a cycle).
      const double back = static_cast<double>(i) - lag_cycles;
      const auto j = static_cast<std::size_t>(std::floor(back));
      const double f = back - static_cast<double>(j);
      auto step = [&](std::size_t k) { return s[k + 1].truth.tip_mm - s[k].truth.tip_mm; };
      moved = std::max(moved, std::abs(s[i].truth.tip_mm - s[j].truth.tip_mm));
      if (std::abs(step(j) - step(j - 1)) > 1e-9 || std::abs(step(j + 1) - step(j)) > 1e-9)
        continue;
      const double truth = s[j].truth.tip_mm + f * step(j);
      worst = std::max(worst, std::abs(s[i].tip - truth));
      ++checked;
    }
    EXPECT_GT(checked, 1000u);
    EXPECT_LT(worst, 1e-6) << "delay " << delay;
    EXPECT_GT(moved, 0.9 * 20.0 * std::floor(lag_cycles) * kDt);  // the shift is visible
  }
}

TEST(SimulatedCatheter, SensorDelayIsInSecondsWhateverTheCyclePeriod) {
  // The controller may run at another period than 1 ms (and one that is not a multiple
  // of the 0.1 ms physics substep); the delay is a time, not a number of cycles. On a
  // steady 10 mm/s ramp the measured tip trails the true tip by exactly v·d.
  const double v = 10.0;
  for (double delay : {0.0, 2e-5, 0.01}) {
    for (double dt : {0.25e-3, 0.3e-3, 0.5e-3, 1e-3, 1.3e-3, 2e-3}) {
      PlantOptions o =
          Noiseless(Options({"coulomb_friction", "viscous_friction", "backlash", "sensor_delay"}));
      o.parameters = {{"sensor_delay.delay_s", delay}};
      CatheterRig rig(o, -10.0, dt);
      const std::vector<Sample> s = After(rig.Track(Ramp(-10.0, v), 1.0), 0.5);
      ASSERT_GT(s.size(), 200u);
      for (const Sample& x : s) {
        ASSERT_NEAR(x.truth.base_velocity_mm_s, v, 1e-3 * v);  // steady, so tip(t) is linear
        ASSERT_NEAR(x.truth.tip_mm - x.tip, v * delay, 1e-3 * v * delay + 1e-9)
            << "dt " << dt << " delay " << delay;
      }
    }
  }
}

TEST(SimulatedCatheter, TipSensorScaleMultipliesTheMeasuredTip) {
  for (double scale : {0.8, 1.03, 1.5}) {
    PlantOptions o = Noiseless(
        Options({"coulomb_friction", "viscous_friction", "backlash", "tip_sensor_scale"}));
    o.parameters = {{"tip_sensor_scale.scale", scale}};
    CatheterRig rig(o, -10.0);
    const std::vector<Sample> s = rig.Track(Triangle(10.0, 20.0), 1.5);
    double span = 0.0;
    for (const Sample& x : s) {
      EXPECT_NEAR(x.tip, scale * x.truth.tip_mm, 1e-12);
      span = std::max(span, std::abs(x.truth.tip_mm));
    }
    EXPECT_GT(span, 5.0);
  }
}

TEST(SimulatedCatheter, SensorDelayAndScaleCompose) {
  // tip_meas(t) = s · tip(t − d), checked on a steady ramp: s · (tip(t) − v d).
  PlantOptions o = Noiseless(Options(
      {"coulomb_friction", "viscous_friction", "backlash", "sensor_delay", "tip_sensor_scale"}));
  o.parameters = {{"sensor_delay.delay_s", 0.02}, {"tip_sensor_scale.scale", 1.1}};
  CatheterRig rig(o, -10.0);
  for (const Sample& x : After(rig.Track(Ramp(-10.0, 10.0), 1.0), 0.5)) {
    EXPECT_NEAR(x.tip, 1.1 * (x.truth.tip_mm - 10.0 * 0.02), 1e-3);
  }
}

// ------------------------------------------------- transmission effects in closed loop

struct FrictionCase {
  std::vector<std::string> effects;
  double tip_load_n;
  double speed;  // mm/s
};

// The model's friction by its equation, from the plant's parameters: every friction
// term summed and multiplied by the capstan factor.
double FrictionByEquation(const TransmissionModel& m, double speed) {
  auto has = [&](const char* e) { return m.HasEffect(e); };
  double f = 0.0;
  if (has("coulomb_friction")) {
    f += m.GetParameter("coulomb_friction.f0_n") +
         m.GetParameter("coulomb_friction.mu_tip") * m.config().tip_load_n;
  }
  if (has("viscous_friction")) f += m.GetParameter("viscous_friction.b_n_per_mm_s") * speed;
  if (has("stribeck_friction")) {
    const double r = speed / m.GetParameter("stribeck_friction.v_stribeck_mm_s");
    f += m.GetParameter("stribeck_friction.delta_static_n") * std::exp(-r * r);
  }
  if (has("capstan_friction")) {
    f *= std::exp(m.GetParameter("capstan_friction.mu") * m.config().TotalBendRad());
  }
  return f;
}

TEST(SimulatedCatheter, ConstantVelocityForceEqualsModelFriction) {
  const std::vector<std::string> seed = {"coulomb_friction", "viscous_friction", "backlash"};
  const std::vector<FrictionCase> cases = {
      {seed, 0.0, 2.0},
      {seed, 0.0, 15.0},
      {seed, 0.0, 40.0},
      {seed, 3.0, 15.0},  // tip load raises the Coulomb level by mu_tip · N
      {{"coulomb_friction", "viscous_friction", "capstan_friction", "backlash"}, 0.0, 15.0},
      {{"coulomb_friction", "viscous_friction", "stribeck_friction", "backlash"}, 0.0, 2.0},
      {{"coulomb_friction", "viscous_friction", "stribeck_friction", "backlash"}, 0.0, 6.0},
  };
  for (const FrictionCase& c : cases) {
    for (double sign : {1.0, -1.0}) {
      PlantOptions o = Options(c.effects);
      o.config.tip_load_n = c.tip_load_n;
      const double start = -sign * 20.0;
      CatheterRig rig(o, start);
      const double v = sign * c.speed;
      const double duration = std::min(1.5, 38.0 / c.speed);
      // Skip the first 0.3 s: the loop settles in a few 1/(ζω) ≈ 2.5 ms.
      const std::vector<Sample> s = After(rig.Track(Ramp(start, v), duration), 0.3);
      ASSERT_GT(s.size(), 500u);
      // Steady: the base moves at v.
      const std::vector<double> vel =
          Collect(s, [](const Sample& x) { return x.truth.base_velocity_mm_s; });
      ASSERT_NEAR(MeanOf(vel), v, 1e-3 * c.speed);
      const double expected = sign * FrictionByEquation(rig.model(), c.speed);
      ASSERT_NEAR(expected, sign * rig.model().FrictionMagnitudeN(c.speed), 1e-12);
      const std::vector<double> force = Collect(s, [](const Sample& x) { return x.sensor; });
      EXPECT_NEAR(MeanOf(force), expected, ForceMeanTolerance(force.size()))
          << FormatModelSpec(c.effects) << " load " << c.tip_load_n << " v " << v;
    }
  }
}

// Hysteresis width of tip vs base on a slow triangle wave: on the way up the tip rides
// the lower band edge (tip − base = −B/2 − ...), on the way down the upper one, so
// mean(tip − base | down) − mean(tip − base | up) = B. Only samples where the base is
// within ±inner of the centre and the tip is engaged count.
double HysteresisWidth(const std::vector<Sample>& s, double inner, std::size_t* n_per_branch) {
  std::vector<double> up, down;
  for (const Sample& x : s) {
    if (std::abs(x.base) > inner) continue;
    (x.truth.base_velocity_mm_s > 0.0 ? up : down).push_back(x.tip - x.base);
  }
  *n_per_branch = std::min(up.size(), down.size());
  return MeanOf(down) - MeanOf(up);
}

double HysteresisTolerance(std::size_t n_per_branch) {
  // Two independent means of n tip samples, quantisation on tip and base.
  return 4.0 * kRigSensors.tip_noise_mm * std::sqrt(2.0 / static_cast<double>(n_per_branch)) +
         0.5 * kRigSensors.tip_quantum_mm + kRigSensors.base_quantum_mm;
}

TEST(SimulatedCatheter, HysteresisWidthIsThetaTimesGap) {
  // Amplitude 8 mm at 4 mm/s: after a reversal the base needs B ≈ 2.5 mm to engage the
  // tip, so |base| < 4 mm is always engaged.
  for (const std::vector<double>& bends :
       {std::vector<double>{90.0, 90.0}, {60.0}, {90.0, 90.0, 90.0}}) {
    PlantOptions o = Options();
    o.config.bends.clear();
    for (double a : bends) o.config.bends.push_back({a, 40.0});
    const double theta = o.config.TotalBendRad();
    const double width = theta * o.config.GapMm();
    CatheterRig rig(o, -8.0);
    const std::vector<Sample> s = After(rig.Track(Triangle(8.0, 4.0), 12.0), 2.0);
    std::size_t n = 0;
    const double measured = HysteresisWidth(s, 4.0, &n);
    ASSERT_GE(n, 2000u);
    EXPECT_NEAR(measured, width, HysteresisTolerance(n)) << "theta " << theta;
  }
}

TEST(SimulatedCatheter, FrictionBacklashWidthInClosedLoop) {
  for (double load : {0.0, 4.0}) {
    PlantOptions o = Options({"coulomb_friction", "viscous_friction", "friction_backlash"});
    o.config.tip_load_n = load;
    CatheterRig rig(o, -8.0);
    const TransmissionModel& m = rig.model();
    const double level =
        m.GetParameter("coulomb_friction.f0_n") + m.GetParameter("coulomb_friction.mu_tip") * load;
    const double width = std::numbers::pi * 0.8 *
                         (m.GetParameter("friction_backlash.a") +
                          m.GetParameter("friction_backlash.b_per_n") * level);
    ASSERT_LT(width, 4.0);  // engaged inside |base| < 4 on an 8 mm triangle
    const std::vector<Sample> s = After(rig.Track(Triangle(8.0, 4.0), 12.0), 2.0);
    std::size_t n = 0;
    const double measured = HysteresisWidth(s, 4.0, &n);
    ASSERT_GE(n, 1000u);
    EXPECT_NEAR(measured, width, HysteresisTolerance(n)) << "load " << load;
  }
}

TEST(SimulatedCatheter, ComplianceWidensTheLoopByTwiceForceOverStiffness) {
  // drive = base − F/k, F = ±F(v) on the two branches: width B + 2 F(v)/k.
  PlantOptions o =
      Options({"coulomb_friction", "viscous_friction", "guidewire_compliance", "backlash"});
  o.parameters = {{"guidewire_compliance.k_n_per_mm", 2.0}};
  CatheterRig rig(o, -8.0);
  const double speed = 4.0;
  const double width = std::numbers::pi * 0.8 + 2.0 * rig.model().FrictionMagnitudeN(speed) / 2.0;
  const std::vector<Sample> s = After(rig.Track(Triangle(8.0, speed), 12.0), 2.0);
  std::size_t n = 0;
  const double measured = HysteresisWidth(s, 3.0, &n);
  ASSERT_GE(n, 1000u);
  EXPECT_NEAR(measured, width, HysteresisTolerance(n));
}

TEST(SimulatedCatheter, DeadzoneTraversalLagsTheBandEdgeByVTau) {
  for (double tau : {0.02, 0.05}) {
    for (double v : {10.0, -25.0}) {
      PlantOptions o =
          Options({"coulomb_friction", "viscous_friction", "backlash", "deadzone_traversal"});
      o.parameters = {{"deadzone_traversal.tau_s", tau}};
      const double start = v > 0 ? -20.0 : 20.0;
      CatheterRig rig(o, start);
      const double half = 0.5 * rig.model().BacklashWidthMm();
      // Engage (B/|v| ≤ 0.25 s) and settle (≥ 5 τ) before measuring.
      const std::vector<Sample> s = After(rig.Track(Ramp(start, v), 1.2), 0.6);
      const double sign = v > 0 ? 1.0 : -1.0;
      // Band edge on the side the base pushes from: drive ∓ B/2.
      const std::vector<double> lag_truth = Collect(s, [&](const Sample& x) {
        return sign * ((x.truth.drive_mm - sign * half) - x.truth.tip_mm);
      });
      const std::vector<double> lag_meas =
          Collect(s, [&](const Sample& x) { return sign * ((x.base - sign * half) - x.tip); });
      EXPECT_NEAR(MeanOf(lag_truth), std::abs(v) * tau, 0.1 * std::abs(v) * tau) << tau << " " << v;
      EXPECT_NEAR(MeanOf(lag_meas), std::abs(v) * tau, 0.1 * std::abs(v) * tau) << tau << " " << v;
    }
  }
  // Without the effect the tip rides the band edge with no lag.
  CatheterRig rig(Options(), -20.0);
  const double half = 0.5 * rig.model().BacklashWidthMm();
  for (const Sample& x : After(rig.Track(Ramp(-20.0, 10.0), 1.0), 0.6)) {
    EXPECT_NEAR(x.truth.tip_mm, x.truth.drive_mm - half, 1e-9);
  }
}

TEST(SimulatedCatheter, DeadzoneTraversalStopsAtOnceOnReversal) {
  // At the top of a triangle the tip trails the band edge by at most v·τ; once the base
  // reverses the band moves away, so the tip can close at most that lag and then must
  // stand still until the base has crossed the deadzone.
  const double speed = 4.0;
  PlantOptions o =
      Options({"coulomb_friction", "viscous_friction", "backlash", "deadzone_traversal"});
  CatheterRig rig(o, -8.0);
  const double width = rig.model().BacklashWidthMm();
  const double tau = rig.model().TraversalTimeConstantS();
  const std::vector<Sample> s = rig.Track(Triangle(8.0, speed), 8.0);
  std::size_t top = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i].truth.base_mm > s[top].truth.base_mm) top = i;
  }
  const double base_top = s[top].truth.base_mm;
  double tip_lo = s[top].truth.tip_mm, tip_hi = tip_lo;
  std::size_t i = top;
  for (; i < s.size() && base_top - s[i].truth.base_mm < 0.5 * width; ++i) {
    tip_lo = std::min(tip_lo, s[i].truth.tip_mm);
    tip_hi = std::max(tip_hi, s[i].truth.tip_mm);
  }
  EXPECT_LE(tip_hi - tip_lo, speed * tau);
  const double parked = s[i].truth.tip_mm;
  std::size_t still = 0;
  for (; i < s.size() && base_top - s[i].truth.base_mm < 0.95 * width; ++i, ++still) {
    EXPECT_EQ(s[i].truth.tip_mm, parked);
  }
  EXPECT_GT(still, 200u);  // ≈ 0.45 B / v ≈ 280 cycles
}

}  // namespace
}  // namespace echoservo::hw
