#include "lab/model_prediction.h"

#include <algorithm>
#include <cmath>

namespace echoservo::lab {
namespace {

// Where the guidewire may be stuck (LabTrial::may_stick) static friction takes whatever
// value balances the drive, anywhere within ±breakaway, and a kinematic model cannot say
// which: the prediction is the measured force clamped to that band, so only a force
// beyond breakaway counts as model error. "May" stick: the base may as well be sliding
// at the estimated speed (a trial's first and last samples, a slow pass), where kinetic
// friction can exceed breakaway (viscous friction), so the band is ±max(breakaway,
// friction magnitude at the estimated speed).

}  // namespace

void PredictTrial(const hw::TransmissionModel& model, const LabTrial& lt,
                  const TrialNuisance& nuisance, Prediction& out) {
  const formats::Trial& tr = lt.trial;
  const std::size_t n = tr.size();
  out.tip_mm.resize(n);
  out.force_n.resize(n);
  std::vector<double>& tip = out.tip_mm;  // true tip first, sensor applied below

  // Friction at every sample's speed, then the force, then the drive, each over the whole
  // trial (one call per effect; the tip buffer holds the speeds, then the drives).
  for (std::size_t i = 0; i < n; ++i) tip[i] = std::abs(lt.velocity_mm_s[i]);
  const bool signals = model.UsesSignals();
  const bool signal_width = model.UsesSignalBacklash();
  std::vector<double> time_s, extra_n;  // signal paths only
  hw::TrialSignals sig;
  if (signals || signal_width) {
    time_s.resize(n);
    for (std::size_t i = 0; i < n; ++i) time_s[i] = tr.t_s[i] - tr.t_s[0];
    sig = {time_s, tr.base_mm, lt.velocity_mm_s, lt.acceleration_mm_s2};
  }
  if (!signals) {
    model.FrictionMagnitudesN(tip, out.force_n);
    const double breakaway = model.FrictionLevelN();
    for (std::size_t i = 0; i < n; ++i) {
      const double kinetic = out.force_n[i];
      const double band = std::max(breakaway, kinetic);
      out.force_n[i] = lt.may_stick[i] != 0 ? std::clamp(tr.force_n[i], -band, band)
                                            : std::copysign(kinetic, lt.velocity_mm_s[i]);
    }
    model.DrivesMm(tr.base_mm, out.force_n, tip);
  } else {
    // Signal effects: friction and breakaway per sample, and the signed extra force, which
    // the force sensor reads on top of friction; the friction band applies to the force
    // left after it. The drive sees the friction alone.
    model.FrictionMagnitudesN(tip, sig, out.force_n);
    extra_n.assign(n, 0.0);
    model.AddForcesN(sig, extra_n);
    // The breakaway matters only where the guidewire may stick: evaluated there alone.
    std::vector<std::size_t> stick;
    for (std::size_t i = 0; i < n; ++i)
      if (lt.may_stick[i] != 0) stick.push_back(i);
    std::vector<double> st_t(stick.size()), st_x(stick.size()), st_v(stick.size()),
        st_a(stick.size()), breakaway(stick.size());
    for (std::size_t k = 0; k < stick.size(); ++k) {
      st_t[k] = time_s[stick[k]];
      st_x[k] = tr.base_mm[stick[k]];
      st_v[k] = lt.velocity_mm_s[stick[k]];
      st_a[k] = lt.acceleration_mm_s2[stick[k]];
    }
    model.BreakawaysN({st_t, st_x, st_v, st_a}, breakaway);
    for (std::size_t i = 0; i < n; ++i)
      if (lt.may_stick[i] == 0) out.force_n[i] = std::copysign(out.force_n[i], lt.velocity_mm_s[i]);
    for (std::size_t k = 0; k < stick.size(); ++k) {
      const std::size_t i = stick[k];
      const double band = std::max(breakaway[k], out.force_n[i]);
      out.force_n[i] = std::clamp(tr.force_n[i] - extra_n[i], -band, band);
    }
    model.DrivesMm(tr.base_mm, out.force_n, tip);
    for (std::size_t i = 0; i < n; ++i) out.force_n[i] += extra_n[i];
  }

  // The deadzone: one width for the trial, or, with a signal backlash effect, the width at
  // each sample's signals (the step into sample i uses sample i's, the initial contact
  // state sample 0's).
  std::vector<double> width;  // signal backlash only
  if (signal_width) {
    width.resize(n);
    model.BacklashWidthsMm(sig, width);
  }
  const double half = 0.5 * model.BacklashWidthMm();
  double last_dt = -1.0;
  double fraction = 1.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double drive = tip[i];
    if (i == 0) {
      tip[0] =
          drive + std::clamp(nuisance.contact, -1.0, 1.0) * (signal_width ? 0.5 * width[0] : half);
    } else {
      const double dt = tr.t_s[i] - tr.t_s[i - 1];
      if (dt != last_dt) {  // uniformly sampled trials compute the exponential once
        fraction = model.TraversalFraction(dt);
        last_dt = dt;
      }
      tip[i] = signal_width ? model.StepTipWithFraction(tip[i - 1], drive, fraction, 0.5 * width[i])
                            : model.StepTipWithFraction(tip[i - 1], drive, fraction);
    }
  }

  // Tip sensor: delay (interpolated on the trial's own time grid), gain, offset. Walk
  // backwards so each value is read before it is overwritten.
  const double delay = model.SensorDelayS();
  const double scale = model.SensorScale();
  if (delay > 0.0) {
    std::size_t j = n - 1;
    for (std::size_t i = n; i-- > 0;) {
      const double t = tr.t_s[i] - delay;
      while (j > 0 && tr.t_s[j] > t) --j;
      double value;
      if (t <= tr.t_s[0]) {
        value = tip[0];
      } else {
        const std::size_t k = std::min(j + 1, n - 1);
        const double span = tr.t_s[k] - tr.t_s[j];
        const double u = span > 0.0 ? (t - tr.t_s[j]) / span : 0.0;
        value = tip[j] + u * (tip[k] - tip[j]);
      }
      tip[i] = value;  // j ≤ i, so later reads (smaller i) only touch indices ≤ i
    }
  }
  if (!signals) {
    for (double& x : tip) x = scale * x + nuisance.tip_offset_mm;
    return;
  }
  // reading = scale·delayed + Σ offsets(delayed, signals) + per-trial offset.
  std::vector<double>& offset = extra_n;  // reused: delayed tip, then delayed + offsets
  offset.assign(tip.begin(), tip.end());
  model.AddSensorOffsetsMm(offset, sig);
  for (std::size_t i = 0; i < n; ++i)
    tip[i] = scale * tip[i] + (offset[i] - tip[i]) + nuisance.tip_offset_mm;
}

}  // namespace echoservo::lab
