// Prediction of a catheter model along a measured trial (lab/model_prediction.h),
// checked on hand-made, noise-free trials against the defining equations: the deadzone
// recurrence for the tip, ±(f0 + μ·load + b|v|) for the force at speed, the measured
// force clamped to the friction band where the guidewire may be stuck, the sensor delay
// as a linear interpolation on the trial's grid, and the per-trial nuisance.
//
// Tolerances: the prediction evaluates the same arithmetic as the references below
// (clamps, sums of O(10) mm or N quantities), so they agree to a few ulps of ~10, i.e.
// ~1e-14; we allow 1e-12. Only the comparison with the analytic base speed (not the
// centred difference the lab uses) needs more: the centred difference over ±5 ms of a
// sine of angular frequency ω has relative bias (ωh)²/6 = (5.03·0.005)²/6 ≈ 1.1e-4, i.e.
// 0.002 mm/s at 20 mm/s, 1.3e-5 N of viscous force; we allow 1e-4 N.
#include "lab/model_prediction.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include "hw/effect_registry.h"
#include "hw/transmission_model.h"
#include "lab/lab_dataset.h"

namespace echoservo::lab {
namespace {

constexpr double kTol = 1e-12;
constexpr double kAmplitudeMm = 4.0;
constexpr double kFrequencyHz = 0.8;
constexpr double kF0 = 0.55;
constexpr double kMuTip = 0.3;
constexpr double kViscous = 0.006;

formats::CatheterConfig PredictionConfig() {
  formats::CatheterConfig c;
  c.sheath_id_mm = 2.38;
  c.guidewire_od_mm = 1.50;
  c.bends = {{90.0, 50.0}, {90.0, 25.0}};  // θ = π, deadzone B = π·0.88 mm
  c.tip_load_n = 0.5;
  return c;
}

double Omega() { return 2.0 * std::numbers::pi * kFrequencyHz; }

// A noise-free trial whose base is `base(t)` at 1 kHz; the measured force sweeps
// ±2.5 N (inside and beyond the breakaway level) so the stick band's clamp shows.
LabTrial MakeTrial(const std::function<double(double)>& base, double duration_s = 3.0) {
  formats::Trial t;
  t.name = "hand_made";
  t.config = PredictionConfig();
  const auto n = static_cast<std::size_t>(std::lround(duration_s * 1000.0));
  for (std::size_t i = 0; i < n; ++i) {
    const double ts = static_cast<double>(i) * 1e-3;
    t.t_s.push_back(ts);
    t.base_cmd_mm.push_back(base(ts));
    t.base_mm.push_back(base(ts));
    t.tip_mm.push_back(0.0);
    t.force_n.push_back(2.5 * std::cos(7.0 * ts));
  }
  return PrepareLabDataset({t}).trials.front();
}

LabTrial SineTrial() {
  return MakeTrial([](double t) { return kAmplitudeMm * std::sin(Omega() * t); });
}

hw::TransmissionModel Model(const std::string& spec) {
  static const hw::EffectRegistry registry = hw::EffectRegistry::WithBuiltinEffects();
  hw::TransmissionModel m(registry, hw::ParseModelSpec(spec, registry), PredictionConfig());
  m.SetParameter("coulomb_friction.f0_n", kF0);
  m.SetParameter("coulomb_friction.mu_tip", kMuTip);
  m.SetParameter("viscous_friction.b_n_per_mm_s", kViscous);
  return m;
}

Prediction Predict(const hw::TransmissionModel& m, const LabTrial& lt,
                   TrialNuisance nuisance = {}) {
  Prediction p;
  PredictTrial(m, lt, nuisance, p);
  return p;
}

TEST(PredictTrial, SeedTipFollowsTheDeadzoneExactly) {
  const LabTrial lt = SineTrial();
  const hw::TransmissionModel m = Model("seed");
  const double width = std::numbers::pi * 0.88;
  ASSERT_NEAR(m.BacklashWidthMm(), width, 1e-12);
  const double half = 0.5 * width;
  const Prediction p = Predict(m, lt);
  ASSERT_EQ(p.tip_mm.size(), lt.trial.size());
  ASSERT_EQ(p.force_n.size(), lt.trial.size());

  // The deadzone recurrence (no compliance: drive = base), tip starting centred.
  double ref = lt.trial.base_mm[0];
  double turn = lt.trial.base_mm[0];  // base at the last turning point
  double last_sign = 1.0;
  int engaged = 0;
  for (std::size_t i = 0; i < lt.trial.size(); ++i) {
    const double b = lt.trial.base_mm[i];
    if (i > 0) ref = std::clamp(ref, b - half, b + half);
    ASSERT_NEAR(p.tip_mm[i], ref, kTol) << "sample " << i;
    // Once the base has moved more than B since it turned, the tip lags it by B/2.
    const double sign = std::cos(Omega() * lt.trial.t_s[i]) >= 0.0 ? 1.0 : -1.0;
    if (sign != last_sign) {
      turn = b;
      last_sign = sign;
    }
    if (std::abs(b - turn) > width + 1e-9) {
      ASSERT_NEAR(p.tip_mm[i], b - sign * half, kTol) << "engaged sample " << i;
      ++engaged;
    }
  }
  // Every half-cycle of 8 mm travel has ≈ (8 − B)/8 of it engaged (in position).
  EXPECT_GT(engaged, 1000);
}

TEST(PredictTrial, ForceAtSpeedIsCoulombPlusViscousOpposingTheMotion) {
  const LabTrial lt = SineTrial();
  const hw::TransmissionModel m = Model("seed");
  const double level = kF0 + kMuTip * PredictionConfig().tip_load_n;
  EXPECT_NEAR(m.FrictionLevelN(), level, kTol);
  const Prediction p = Predict(m, lt);
  int sliding = 0;
  for (std::size_t i = 0; i < lt.trial.size(); ++i) {
    if (lt.may_stick[i] != 0) continue;
    const double v = lt.velocity_mm_s[i];
    ASSERT_NEAR(p.force_n[i], std::copysign(level + kViscous * std::abs(v), v), kTol)
        << "sample " << i;
    // The lab's centred-difference speed is the analytic one up to its small bias.
    const double v_true = kAmplitudeMm * Omega() * std::cos(Omega() * lt.trial.t_s[i]);
    if (lt.trial.t_s[i] > 0.01 && lt.trial.t_s[i] < 2.99) {
      ASSERT_NEAR(p.force_n[i], std::copysign(level + kViscous * std::abs(v_true), v_true), 1e-4)
          << "sample " << i;
    }
    ++sliding;
  }
  // Only the samples around the 5 reversals and the trial's ends may stick: near a
  // reversal |v| < 1 mm/s for ±1/(Aω²) ≈ ±10 ms, widened by ±5 ms: ≈ 30 samples each.
  EXPECT_GT(sliding, static_cast<int>(lt.trial.size()) - 200);
}

TEST(PredictTrial, WhereTheGuidewireMayStickTheForceIsTheMeasuredOneClamped) {
  const double level = kF0 + kMuTip * PredictionConfig().tip_load_n;
  const hw::TransmissionModel m = Model("seed");
  {
    // Around reversals of the sine: the measured force, clamped to the band allowed
    // there: breakaway, or the kinetic friction at the estimated speed where larger.
    const LabTrial lt = SineTrial();
    const Prediction p = Predict(m, lt);
    int stuck = 0, clamped = 0;
    for (std::size_t i = 0; i < lt.trial.size(); ++i) {
      if (lt.may_stick[i] == 0) continue;
      const double band = level + kViscous * std::abs(lt.velocity_mm_s[i]);
      ASSERT_NEAR(p.force_n[i], std::clamp(lt.trial.force_n[i], -band, band), kTol)
          << "sample " << i;
      ++stuck;
      clamped += std::abs(lt.trial.force_n[i]) > band;
    }
    EXPECT_GT(stuck, 20);
    EXPECT_GT(clamped, 0);
    EXPECT_LT(clamped, stuck);
  }
  {
    // A base at rest for 0.5 s, then a ramp: at rest the band is exactly ±breakaway.
    const LabTrial lt =
        MakeTrial([](double t) { return t < 0.5 ? 1.0 : 1.0 + 10.0 * (t - 0.5); }, 1.0);
    const Prediction p = Predict(m, lt);
    int inside = 0, beyond = 0;
    for (std::size_t i = 0; i < 490; ++i) {
      ASSERT_EQ(lt.may_stick[i], 1);
      ASSERT_EQ(lt.velocity_mm_s[i], 0.0);
      const double f = lt.trial.force_n[i];
      if (std::abs(f) <= level) {
        EXPECT_NEAR(p.force_n[i], f, kTol) << "within the band the measurement is the prediction";
        ++inside;
      } else {
        EXPECT_NEAR(p.force_n[i], std::copysign(level, f), kTol)
            << "beyond breakaway is model error";
        ++beyond;
      }
    }
    EXPECT_GT(inside, 50);
    EXPECT_GT(beyond, 50);
    // Well into the ramp the force is kinetic again: f0 + μ·load + b·10.
    for (std::size_t i = 520; i < 990; ++i) {
      ASSERT_EQ(lt.may_stick[i], 0) << i;
      ASSERT_NEAR(p.force_n[i], level + kViscous * 10.0, 1e-9) << i;
    }
  }
}

// Linear interpolation of `x` (on the trial's grid) at time t; the first value before it.
double Interpolate(const std::vector<double>& t, const std::vector<double>& x, double at) {
  if (at <= t.front()) return x.front();
  const auto k = static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), at) - t.begin());
  if (k >= t.size()) return x.back();
  const double u = (at - t[k - 1]) / (t[k] - t[k - 1]);
  return x[k - 1] + u * (x[k] - x[k - 1]);
}

TEST(PredictTrial, SensorDelayShiftsTheTipByTheDelay) {
  const LabTrial lt = SineTrial();
  const Prediction undelayed = Predict(Model("seed"), lt);
  for (double delay : {0.005, 0.0123, 0.05}) {
    hw::TransmissionModel m = Model("seed+sensor_delay");
    m.SetParameter("sensor_delay.delay_s", delay);
    ASSERT_DOUBLE_EQ(m.SensorDelayS(), delay);
    const Prediction p = Predict(m, lt);
    for (std::size_t i = 0; i < lt.trial.size(); ++i) {
      const double ref = Interpolate(lt.trial.t_s, undelayed.tip_mm, lt.trial.t_s[i] - delay);
      ASSERT_NEAR(p.tip_mm[i], ref, 1e-9) << "delay " << delay << ", sample " << i;
      // The delay is a sensor property: the friction force is not delayed.
      ASSERT_EQ(p.force_n[i], undelayed.force_n[i]);
    }
    // A whole number of samples is a plain shift.
    if (delay == 0.005) {
      for (std::size_t i = 5; i < lt.trial.size(); ++i)
        ASSERT_NEAR(p.tip_mm[i], undelayed.tip_mm[i - 5], 1e-9);
    }
  }
}

TEST(PredictTrial, OffsetAddsAfterTheSensorGain) {
  const LabTrial lt = SineTrial();
  const Prediction base = Predict(Model("seed"), lt);
  const Prediction offset = Predict(Model("seed"), lt, {0.37, 0.0});
  hw::TransmissionModel scaled_model = Model("seed+tip_sensor_scale");
  scaled_model.SetParameter("tip_sensor_scale.scale", 1.1);
  const Prediction scaled = Predict(scaled_model, lt, {-0.2, 0.0});
  for (std::size_t i = 0; i < lt.trial.size(); ++i) {
    ASSERT_NEAR(offset.tip_mm[i], base.tip_mm[i] + 0.37, kTol);
    ASSERT_NEAR(scaled.tip_mm[i], 1.1 * base.tip_mm[i] - 0.2, kTol);
    ASSERT_EQ(offset.force_n[i], base.force_n[i]);
    ASSERT_EQ(scaled.force_n[i], base.force_n[i]);
  }
}

TEST(PredictTrial, ContactSetsTheInitialTipAndIsForgottenOnceEngaged) {
  const LabTrial lt = SineTrial();
  const hw::TransmissionModel m = Model("seed");
  const double half = 0.5 * m.BacklashWidthMm();
  const double b0 = lt.trial.base_mm[0];
  const Prediction up = Predict(m, lt, {0.0, 1.0});
  const Prediction beyond = Predict(m, lt, {0.0, 5.0});  // clamped to 1
  const Prediction down = Predict(m, lt, {0.1, -0.5});
  EXPECT_NEAR(up.tip_mm[0], b0 + half, kTol);
  EXPECT_NEAR(down.tip_mm[0], b0 - 0.5 * half + 0.1, kTol);
  for (std::size_t i = 0; i < lt.trial.size(); ++i) ASSERT_EQ(beyond.tip_mm[i], up.tip_mm[i]);
  // The base rises first: with c = 1 the tip waits at b0 + B/2 until the base has risen
  // by B, and from then on every initial state gives the same tip.
  std::size_t engaged = 0;
  while (lt.trial.base_mm[engaged] - b0 <= 2.0 * half + 1e-9) {
    EXPECT_NEAR(up.tip_mm[engaged], b0 + half, kTol) << engaged;
    ++engaged;
  }
  for (std::size_t i = engaged; i < lt.trial.size(); ++i) {
    ASSERT_NEAR(up.tip_mm[i], down.tip_mm[i] - 0.1, kTol) << i;
  }
}

TEST(PredictTrial, ComplianceOffsetsTheDriveByTheFrictionForce) {
  // guidewire_compliance: the drive lags the base by F/k, so in engaged motion the tip
  // is base − F/k − sign(v)·B/2 with F the predicted friction force.
  const LabTrial lt = SineTrial();
  hw::TransmissionModel m = Model("seed+guidewire_compliance");
  m.SetParameter("guidewire_compliance.k_n_per_mm", 10.0);
  const Prediction p = Predict(m, lt);
  const double half = 0.5 * m.BacklashWidthMm();
  int checked = 0;
  for (std::size_t i = 1; i < lt.trial.size(); ++i) {
    const double drive = m.DriveMm(lt.trial.base_mm[i], p.force_n[i]);
    ASSERT_NEAR(drive, lt.trial.base_mm[i] - p.force_n[i] / 10.0, kTol);
    if (std::abs(p.tip_mm[i] - drive) > half - 1e-9) ++checked;  // on a band edge
    ASSERT_LE(std::abs(p.tip_mm[i] - drive), half + kTol) << i;
  }
  EXPECT_GT(checked, 1000);
}

}  // namespace
}  // namespace echoservo::lab
