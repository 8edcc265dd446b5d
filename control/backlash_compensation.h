// Backlash compensation: turns the desired tip trajectory into a base command.
//
// A BacklashCompensator sees the reference r (known ahead of time: a test trajectory or the
// estimator's Fourier prediction) and the measured tip (mm), and returns the base position
// and velocity to command (mm, mm/s). Implementations: NoCompensation (base = r);
// StaticInverse (a fixed deadzone width, the switch taken early, an optional time advance);
// IterativeInverse (the seed's between-runs learning table); AdaptiveInverse (width, lag and
// offset estimated online by RLS). Extension point: derive and implement DoCalc.
// Errors: std::invalid_argument for invalid parameters (see each constructor and options).
// Details: docs/control.md#backlash-compensation
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "control/trajectory.h"

namespace echoservo::control {

struct BaseCommand {
  double position_mm = 0.0;
  double velocity_mm_s = 0.0;
};

struct CompensatorInput {
  double t_s = 0.0;
  std::size_t cycle = 0;  // index since the start of the run
  double period_s = 1e-3;
  const Trajectory* reference = nullptr;
  double tip_measured_mm = 0.0;
};

class BacklashCompensator {
 public:
  virtual ~BacklashCompensator() = default;
  BaseCommand Calc(const CompensatorInput& in) { return DoCalc(in); }
  virtual std::string name() const = 0;
  // Called at the start of every run.
  virtual void Reset() {}

 protected:
  virtual BaseCommand DoCalc(const CompensatorInput& in) = 0;
};

class NoCompensation final : public BacklashCompensator {
 public:
  std::string name() const override { return "none"; }

 protected:
  BaseCommand DoCalc(const CompensatorInput& in) override;
};

// Direction of the reference motion `lead_s` ahead, with a dead band so that noise-
// free trajectories switch exactly once per reversal.
class DirectionTracker {
 public:
  explicit DirectionTracker(double threshold_mm_s = 0.5) : threshold_(threshold_mm_s) {}
  void Reset() { sign_ = 0.0; }
  // Returns +1 or −1 (0 before the reference has first moved); true in `switched`
  // when the sign changed on this call.
  double Update(double lookahead_velocity_mm_s, bool* switched);

 private:
  double threshold_;
  double sign_ = 0.0;
};

class StaticInverse final : public BacklashCompensator {
 public:
  // Throws std::invalid_argument for a negative/non-finite width or acceleration, or a
  // time advance outside [0, 0.1] s.
  StaticInverse(double width_mm, double max_acceleration_mm_s2, double time_advance_s = 0.0);
  std::string name() const override { return "inverse"; }
  void Reset() override { direction_.Reset(); }
  double lead_s() const { return lead_s_; }
  double time_advance_s() const { return time_advance_s_; }

 protected:
  BaseCommand DoCalc(const CompensatorInput& in) override;

 private:
  double width_mm_;
  double lead_s_;
  double time_advance_s_;
  DirectionTracker direction_;
};

struct IterativeOptions {
  double learning_gain = 1.0;  // the seed adds the whole error
};

class IterativeInverse final : public BacklashCompensator {
 public:
  explicit IterativeInverse(IterativeOptions options = {});
  std::string name() const override { return "iterative"; }
  // After a run: correction[k] += gain · error[k] (error = reference − measured tip).
  void Learn(const std::vector<double>& tip_error_mm);
  const std::vector<double>& correction_mm() const { return correction_mm_; }

 protected:
  BaseCommand DoCalc(const CompensatorInput& in) override;

 private:
  IterativeOptions options_;
  std::vector<double> correction_mm_;
};

struct AdaptiveOptions {
  double initial_width_mm = 0.0;
  double max_acceleration_mm_s2 = 60000.0;  // for the reversal lead
  double forgetting = 0.9995;               // RLS forgetting factor per cycle
  double settle_after_reversal_s = 0.08;    // skip the crossing transient
  double min_speed_mm_s = 3.0;              // learn only in engaged motion
  double initial_uncertainty = 1.0;         // P0 diagonal (mm², s², mm²)
  double innovation_gate_mm = 1.0;          // larger prediction errors are not learned from
  void Validate() const;
};

class AdaptiveInverse final : public BacklashCompensator {
 public:
  explicit AdaptiveInverse(AdaptiveOptions options);
  std::string name() const override { return "adaptive"; }
  void Reset() override;
  double width_mm() const { return theta_(0); }
  double lag_s() const { return theta_(1); }
  double offset_mm() const { return theta_(2); }

 protected:
  BaseCommand DoCalc(const CompensatorInput& in) override;

 private:
  AdaptiveOptions options_;
  DirectionTracker direction_;
  Eigen::Vector3d theta_;  // [W, τ, o]
  Eigen::Matrix3d p_;
  double p0_trace_ = 0.0;
  double last_switch_s_ = -1e9;
};

}  // namespace echoservo::control
