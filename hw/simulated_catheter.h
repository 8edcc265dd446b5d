// The simulated catheter: a full HardwareInterface implementation of the voice-coil
// catheter drive, for simulation, tests and the closed-loop demo.
//
// Mechanics: a voice coil (force constant × amplifier current, current limited, first-
// order current loop) moves a slide of mass m over ±travel/2 with end stops; the slide
// pushes the guidewire, whose friction (from the TransmissionModel, with stick-slip at
// the breakaway level) opposes the slide and is what the force sensor reads. Effects with
// signal hooks (hw/effect.h) see the time since ResetTo, the slide's position, velocity
// and acceleration (of the last substep): their extra force (TransmissionModel::ForceN)
// also opposes the drive and is read by the force sensor, their signal friction adds to
// the friction and breakaway, their sensor offset to the tip reading. The tip
// follows the drive position through the deadzone of the model (with a signal backlash
// hook, of the width at the same signals, substep by substep). Sensors add Gaussian
// noise and quantisation. Units: mm, mm/s, N, A, s. Base position 0 is mid-travel.
//
// State interfaces: base/position, base/velocity, actuator/current, actuator/force,
// force_sensor/force, tip/position, fault/count. Command interface: actuator/force (N).
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "hw/delay_line.h"
#include "hw/hardware_interface.h"
#include "hw/transmission_model.h"

namespace echoservo::hw {

struct ActuatorParams {
  double force_constant_n_per_a = 8.9;  // 26.7 N at the 3 A amplifier limit
  double current_limit_a = 3.0;
  double current_time_constant_s = 3e-4;
  double moving_mass_kg = 0.25;  // coil, slide, force sensor, guidewire clamp
  double travel_mm = 50.8;
  double end_stop_stiffness_n_per_mm = 200.0;
  double PeakForceN() const { return force_constant_n_per_a * current_limit_a; }
};

struct SensorParams {
  double tip_noise_mm = 0.03;  // 1σ, potentiometer
  double tip_quantum_mm = 0.0125;
  double force_noise_n = 0.0075;  // 1σ; ±0.015 N at 2σ
  double force_quantum_n = 0.002;
  double base_quantum_mm = 0.001;  // encoder
};

struct PlantOptions {
  formats::CatheterConfig config = formats::CatheterConfig::SeedEvaluation();
  std::vector<std::string> effects = {"coulomb_friction", "viscous_friction", "backlash"};
  // "<effect>.<parameter>" = value, applied over the effects' defaults.
  std::vector<std::pair<std::string, double>> parameters;
  ActuatorParams actuator;
  SensorParams sensors;
  int substeps = 10;  // physics steps per write(t, dt)
  // Where effect names are looked up; null: DefaultEffectRegistry() (the built-in catalog
  // unless a program installed its own). A registry with a user's own effects must outlive
  // the plant's construction.
  const EffectRegistry* registry = nullptr;
  std::uint64_t seed = 1;
  bool sensor_noise = true;
};

// Ground truth the simulator knows and a real rig does not (for tests and datasets).
struct PlantTruth {
  double base_mm = 0.0;
  double base_velocity_mm_s = 0.0;
  double drive_mm = 0.0;
  double tip_mm = 0.0;
  double friction_force_n = 0.0;
  double extra_force_n = 0.0;       // the effects' signal force (ForceN), 0 without one
  double acceleration_mm_s2 = 0.0;  // of the last substep
  double time_s = 0.0;              // since ResetTo
  bool stuck = true;
};

class SimulatedCatheter final : public HardwareInterface {
 public:
  // Throws std::invalid_argument for an invalid geometry, unknown effect or parameter.
  explicit SimulatedCatheter(PlantOptions options);

  const TransmissionModel& model() const { return model_; }
  const PlantOptions& options() const { return options_; }
  const PlantTruth& truth() const { return truth_; }
  // Places the slide at `base_mm` at rest with the tip centred in the deadzone.
  void ResetTo(double base_mm);

 protected:
  void DoConfigure() override;
  void DoActivate() override;
  void DoRead(double t_s, double dt_s) override;
  void DoWrite(double t_s, double dt_s) override;

 private:
  void Substep(double h_s, double current_cmd_a);
  void SubstepMechanics(double h_s, double applied_n);
  SampleSignals Signals() const;
  double Quantise(double v, double q) const;
  // The tip history is sampled every history_period_s_ of simulated time whatever the
  // substep h (write() may be called with any dt): RecordTip resamples the tip between
  // substeps, DelayedTip reads it `delay_s` before now.
  void RecordTip(double tip_before_mm, double tip_after_mm, double h_s);
  double DelayedTip(double delay_s) const;

  PlantOptions options_;
  TransmissionModel model_;
  DelayLine tip_history_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  PlantTruth truth_;
  double history_period_s_;
  double since_push_s_ = 0.0;  // simulated time since the newest tip history sample
  double current_a_ = 0.0;
  double faults_ = 0.0;
  std::size_t s_base_, s_vel_, s_current_, s_force_, s_sensor_, s_tip_, s_fault_, c_force_;
};

}  // namespace echoservo::hw
