#include "lab/residual_breakdown.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>

namespace echoservo::lab {
namespace {

constexpr double kReversalWindowS = 0.08;
constexpr double kRestSpeedMmS = 1.0;
constexpr double kSpeedBins[] = {0.0, 2.0, 10.0, 30.0, 100.0};

struct Accumulator {
  std::size_t n = 0;
  double tip_ss = 0.0;
  double force_ss = 0.0;
};

std::string Label(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::vector<GroupStat> Finish(const std::map<double, std::pair<std::string, Accumulator>>& groups,
                              const Accumulator& total) {
  std::vector<GroupStat> out;
  for (const auto& [key, entry] : groups) {
    const Accumulator& a = entry.second;
    if (a.n == 0) continue;
    GroupStat g;
    g.label = entry.first;
    g.value = key;
    g.samples = a.n;
    g.tip_rms_mm = std::sqrt(a.tip_ss / static_cast<double>(a.n));
    g.force_rms_n = std::sqrt(a.force_ss / static_cast<double>(a.n));
    g.sample_share = static_cast<double>(a.n) / static_cast<double>(total.n);
    g.tip_share = total.tip_ss > 0.0 ? a.tip_ss / total.tip_ss : 0.0;
    g.force_share = total.force_ss > 0.0 ? a.force_ss / total.force_ss : 0.0;
    out.push_back(g);
  }
  return out;
}

}  // namespace

double AccelerationThreshold(const LabDataset& ds) {
  std::vector<double> a;
  for (const LabTrial& t : ds.trials) {
    for (double v : t.acceleration_mm_s2) a.push_back(std::abs(v));
  }
  if (a.empty()) return 0.0;
  const auto p95 =
      a.begin() + static_cast<std::ptrdiff_t>(0.95 * static_cast<double>(a.size() - 1));
  std::nth_element(a.begin(), p95, a.end());
  return std::max(0.25 * *p95, 10.0);
}

std::vector<std::string> ClassifyPhases(const LabTrial& lt, double accel_threshold) {
  const std::size_t n = lt.trial.size();
  std::vector<std::string> phase(n);
  double sign = 0.0;
  double last_reversal = -1e9;
  for (std::size_t i = 0; i < n; ++i) {
    const double v = lt.velocity_mm_s[i];
    const double t = lt.trial.t_s[i];
    if (std::abs(v) >= kRestSpeedMmS) {
      const double s = v > 0.0 ? 1.0 : -1.0;
      if (sign != 0.0 && s != sign) last_reversal = t;
      sign = s;
    }
    if (t - last_reversal < kReversalWindowS) {
      phase[i] = "after_reversal";
    } else if (std::abs(v) < kRestSpeedMmS) {
      phase[i] = "rest";
    } else if (std::abs(lt.acceleration_mm_s2[i]) > accel_threshold) {
      phase[i] = "acceleration";
    } else {
      phase[i] = "constant_velocity";
    }
  }
  return phase;
}

Breakdown ComputeBreakdown(const LabDataset& ds, const FitResult& fit) {
  const double accel = AccelerationThreshold(ds);
  std::map<double, std::pair<std::string, Accumulator>> phase, speed, gap, bend, load, trial;
  const std::map<std::string, double> phase_order = {
      {"after_reversal", 0}, {"acceleration", 1}, {"constant_velocity", 2}, {"rest", 3}};
  Accumulator total;
  const std::size_t trials = std::min(ds.trials.size(), fit.trials.size());
  for (std::size_t k = 0; k < trials; ++k) {
    const LabTrial& lt = ds.trials[k];
    const Prediction& p = fit.trials[k].prediction;
    const std::vector<std::string> phases = ClassifyPhases(lt, accel);
    const double g = std::round(lt.trial.config.GapMm() * 100.0) / 100.0;
    const double b = std::round(lt.trial.config.TotalBendRad() * 180.0 / std::numbers::pi);
    const double l = std::round(lt.trial.config.tip_load_n * 100.0) / 100.0;
    for (std::size_t i = 0; i < lt.trial.size(); ++i) {
      const double et = p.tip_mm[i] - lt.trial.tip_mm[i];
      const double ef = p.force_n[i] - lt.trial.force_n[i];
      auto add = [&](std::map<double, std::pair<std::string, Accumulator>>& m, double key,
                     const std::string& label) {
        auto& e = m[key];
        e.first = label;
        e.second.n += 1;
        e.second.tip_ss += et * et;
        e.second.force_ss += ef * ef;
      };
      add(phase, phase_order.at(phases[i]), phases[i]);
      const double sp = std::abs(lt.velocity_mm_s[i]);
      double bin = kSpeedBins[0];
      for (double edge : kSpeedBins) {
        if (sp >= edge) bin = edge;
      }
      add(speed, bin,
          bin >= 100.0 ? std::string(">= 100 mm/s")
                       : Label("%.0f", bin) + "–" +
                             Label("%.0f mm/s", *std::upper_bound(std::begin(kSpeedBins),
                                                                  std::end(kSpeedBins), bin)));
      add(gap, g, Label("gap %.2f mm", g));
      add(bend, b, Label("bend %.0f deg", b));
      add(load, l, Label("tip load %.2f N", l));
      add(trial, static_cast<double>(k), lt.trial.name);
      total.n += 1;
      total.tip_ss += et * et;
      total.force_ss += ef * ef;
    }
  }
  Breakdown out;
  out.phase = Finish(phase, total);
  out.speed = Finish(speed, total);
  out.gap = Finish(gap, total);
  out.bend = Finish(bend, total);
  out.tip_load = Finish(load, total);
  out.trial = Finish(trial, total);
  return out;
}

}  // namespace echoservo::lab
