#include "hw/simulated_catheter.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace echoservo::hw {
namespace {

constexpr double kMmPerM = 1000.0;  // F/m in N/kg = m/s², ×1000 for mm/s²

TransmissionModel MakeModel(const PlantOptions& o) {
  TransmissionModel model(o.registry != nullptr ? *o.registry : DefaultEffectRegistry(), o.effects,
                          o.config);
  for (const auto& [name, value] : o.parameters) model.SetParameter(name, value);
  return model;
}

void ValidateOptions(const PlantOptions& o) {
  const ActuatorParams& a = o.actuator;
  auto require = [](bool ok, const char* field) {
    if (!ok)
      throw std::invalid_argument(std::string("plant options: '") + field +
                                  "' must be finite and > 0");
  };
  require(std::isfinite(a.force_constant_n_per_a) && a.force_constant_n_per_a > 0,
          "actuator.force_constant_n_per_a");
  require(std::isfinite(a.current_limit_a) && a.current_limit_a > 0, "actuator.current_limit_a");
  require(std::isfinite(a.current_time_constant_s) && a.current_time_constant_s > 0,
          "actuator.current_time_constant_s");
  require(std::isfinite(a.moving_mass_kg) && a.moving_mass_kg > 0, "actuator.moving_mass_kg");
  require(std::isfinite(a.travel_mm) && a.travel_mm > 0, "actuator.travel_mm");
  require(std::isfinite(a.end_stop_stiffness_n_per_mm) && a.end_stop_stiffness_n_per_mm > 0,
          "actuator.end_stop_stiffness_n_per_mm");
  require(o.substeps > 0 && o.substeps <= 1000, "substeps");
  const SensorParams& s = o.sensors;
  auto require_sensor = [](double v, const char* field) {
    if (!(std::isfinite(v) && v >= 0.0)) {
      throw std::invalid_argument(std::string("plant options: '") + field +
                                  "' must be finite and >= 0");
    }
  };
  require_sensor(s.tip_noise_mm, "sensors.tip_noise_mm");
  require_sensor(s.tip_quantum_mm, "sensors.tip_quantum_mm");
  require_sensor(s.force_noise_n, "sensors.force_noise_n");
  require_sensor(s.force_quantum_n, "sensors.force_quantum_n");
  require_sensor(s.base_quantum_mm, "sensors.base_quantum_mm");
}

}  // namespace

SimulatedCatheter::SimulatedCatheter(PlantOptions options)
    : options_((ValidateOptions(options), std::move(options))),
      model_(MakeModel(options_)),
      tip_history_(1e-3 / options_.substeps, 0.1 + 1e-3),
      rng_(options_.seed),
      history_period_s_(1e-3 / options_.substeps) {
  s_base_ = AddStateInterface(std::string(iface::kBasePosition), "mm");
  s_vel_ = AddStateInterface(std::string(iface::kBaseVelocity), "mm/s");
  s_current_ = AddStateInterface(std::string(iface::kActuatorCurrent), "A");
  s_force_ = AddStateInterface(std::string(iface::kActuatorForce), "N");
  s_sensor_ = AddStateInterface(std::string(iface::kSensorForce), "N");
  s_tip_ = AddStateInterface(std::string(iface::kTipPosition), "mm");
  s_fault_ = AddStateInterface(std::string(iface::kFaultCount), "1");
  c_force_ = AddCommandInterface(std::string(iface::kActuatorForce), "N");
  ResetTo(0.0);
}

void SimulatedCatheter::ResetTo(double base_mm) {
  const double half = 0.5 * options_.actuator.travel_mm;
  if (!std::isfinite(base_mm) || std::abs(base_mm) > half) {
    throw std::invalid_argument("simulated catheter: reset position outside travel");
  }
  truth_ = PlantTruth{};
  truth_.base_mm = base_mm;
  truth_.drive_mm = model_.DriveMm(base_mm, 0.0);
  truth_.tip_mm = truth_.drive_mm;
  current_a_ = 0.0;
  tip_history_.Reset(truth_.tip_mm);
  since_push_s_ = 0.0;
}

void SimulatedCatheter::DoConfigure() { ResetTo(truth_.base_mm); }

void SimulatedCatheter::DoActivate() { current_a_ = 0.0; }

double SimulatedCatheter::Quantise(double v, double q) const {
  return q > 0.0 ? q * std::round(v / q) : v;
}

void SimulatedCatheter::DoRead(double, double) {
  const SensorParams& s = options_.sensors;
  const double noise = options_.sensor_noise ? 1.0 : 0.0;
  const double delayed = DelayedTip(model_.SensorDelayS());
  double tip_true = model_.SensorScale() * delayed;
  double force_true = truth_.friction_force_n;
  if (model_.UsesSignals()) {
    tip_true += model_.SensorOffsetMm(delayed, Signals());
    force_true += truth_.extra_force_n;
  }
  set_state(s_base_, Quantise(truth_.base_mm, s.base_quantum_mm));
  set_state(s_vel_, truth_.base_velocity_mm_s);
  set_state(s_current_, current_a_);
  set_state(s_force_, current_a_ * options_.actuator.force_constant_n_per_a);
  set_state(s_sensor_,
            Quantise(force_true + noise * s.force_noise_n * normal_(rng_), s.force_quantum_n));
  set_state(s_tip_, Quantise(tip_true + noise * s.tip_noise_mm * normal_(rng_), s.tip_quantum_mm));
  set_state(s_fault_, faults_);
}

void SimulatedCatheter::DoWrite(double, double dt_s) {
  const ActuatorParams& a = options_.actuator;
  double force_cmd = command(c_force_);
  if (!std::isfinite(force_cmd)) {  // the amplifier ignores a non-finite command
    force_cmd = 0.0;
    faults_ += 1.0;
  }
  const double current_cmd =
      std::clamp(force_cmd / a.force_constant_n_per_a, -a.current_limit_a, a.current_limit_a);
  const double h = dt_s / options_.substeps;
  for (int i = 0; i < options_.substeps; ++i) Substep(h, current_cmd);
}

void SimulatedCatheter::Substep(double h, double current_cmd_a) {
  const ActuatorParams& a = options_.actuator;
  current_a_ += (current_cmd_a - current_a_) * (1.0 - std::exp(-h / a.current_time_constant_s));
  double applied_n = current_a_ * a.force_constant_n_per_a;
  const double half = 0.5 * a.travel_mm;
  if (truth_.base_mm > half) applied_n -= a.end_stop_stiffness_n_per_mm * (truth_.base_mm - half);
  if (truth_.base_mm < -half) applied_n -= a.end_stop_stiffness_n_per_mm * (truth_.base_mm + half);

  SubstepMechanics(h, applied_n);
}

SampleSignals SimulatedCatheter::Signals() const {
  return {truth_.time_s, truth_.base_mm, truth_.base_velocity_mm_s, truth_.acceleration_mm_s2};
}

// The slide's mechanics over one substep, with the effects' signal hooks: the extra force
// opposes the drive like a load (it is not friction, so it does not stick), breakaway and
// kinetic friction include the signal friction at this sample. Without signal effects the
// extra force is 0 and the friction the model's plain values, bit for bit. The deadzone
// width, where it changes with the signals, is the one at this substep's signals too.
void SimulatedCatheter::SubstepMechanics(double h, double applied_n) {
  PlantTruth& s = truth_;
  const double accel_per_n = kMmPerM / options_.actuator.moving_mass_kg;  // mm/s² per N
  const SampleSignals signals = Signals();
  const double v = s.base_velocity_mm_s;
  s.extra_force_n = model_.ForceN(signals);
  const double net_n = applied_n - s.extra_force_n;
  if (s.stuck) {
    const double breakaway = model_.BreakawayN(signals);
    if (std::abs(net_n) <= breakaway) {
      s.friction_force_n = net_n;  // static friction balances the drive
      s.base_velocity_mm_s = 0.0;
    } else {
      s.stuck = false;
      s.friction_force_n = std::copysign(breakaway, net_n);
      s.base_velocity_mm_s += h * (net_n - s.friction_force_n) * accel_per_n;
    }
  } else {
    s.friction_force_n = std::copysign(model_.FrictionMagnitudeN(std::abs(v), signals), v);
    const double v_next = v + h * (net_n - s.friction_force_n) * accel_per_n;
    if (v != 0.0 && v_next * v <= 0.0) {  // sliding stopped within the step
      s.base_velocity_mm_s = 0.0;
      s.stuck = true;
    } else {
      s.base_velocity_mm_s = v_next;
    }
  }
  s.acceleration_mm_s2 = (s.base_velocity_mm_s - v) / h;
  s.time_s += h;
  s.base_mm += h * s.base_velocity_mm_s;
  s.drive_mm = model_.DriveMm(s.base_mm, s.friction_force_n);
  const double tip_before = s.tip_mm;
  s.tip_mm = model_.UsesSignalBacklash()
                 ? model_.StepTip(s.tip_mm, s.drive_mm, h, 0.5 * model_.BacklashWidthMm(signals))
                 : model_.StepTip(s.tip_mm, s.drive_mm, h);
  RecordTip(tip_before, s.tip_mm, h);
}

void SimulatedCatheter::RecordTip(double tip_before_mm, double tip_after_mm, double h_s) {
  // Push one sample per history period, linearly interpolated within this substep (with
  // the 1 ms cycle, h equals the period and this pushes exactly the new tip).
  double since = since_push_s_ + h_s;  // time from the last sample to the end of this substep
  while (since >= history_period_s_ * (1.0 - 1e-9)) {
    since -= history_period_s_;
    const double at = std::clamp((h_s - since) / h_s, 0.0, 1.0);
    tip_history_.Push(tip_before_mm + at * (tip_after_mm - tip_before_mm));
  }
  since_push_s_ = std::max(since, 0.0);
}

double SimulatedCatheter::DelayedTip(double delay_s) const {
  // The newest history sample is since_push_s_ old; younger delays interpolate between
  // it and the current tip.
  if (delay_s >= since_push_s_) return tip_history_.Delayed(delay_s - since_push_s_);
  const double newest = tip_history_.Delayed(0.0);
  return truth_.tip_mm + (newest - truth_.tip_mm) * (delay_s / since_push_s_);
}

}  // namespace echoservo::hw
