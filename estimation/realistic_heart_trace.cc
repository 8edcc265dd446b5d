#include "estimation/realistic_heart_trace.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

namespace echoservo::estimation {
namespace {

constexpr double kGenPi = std::numbers::pi;
constexpr double kWanderTauS = 10.0;    // heart-rate wander correlation time
constexpr double kRelaxTauS = 0.09;     // diastolic relaxation time constant
constexpr double kKickS = 0.14;         // atrial kick duration
constexpr double kKickFraction = 0.18;  // its height, fraction of the beat amplitude
constexpr double kPrematureFraction = 0.65;
constexpr double kEctopicStrength = 0.6;  // premature beat amplitude
constexpr double kPostEctopicStrength = 1.15;

struct GenBeat {
  double start_s;
  double duration_s;
  double strength;
};

bool GenFinite(double v) { return std::isfinite(v); }

// The wall position within a beat of duration d at τ s after its start, 0 at both ends.
double BeatShape(double tau, double d) {
  const double systole = std::min(0.3 * std::sqrt(d), 0.45 * d);
  if (tau < systole) return 0.5 * (1.0 - std::cos(kGenPi * tau / systole));
  const double diastole = d - systole;
  const double u = tau - systole;
  const double end = std::exp(-diastole / kRelaxTauS);
  double y = (std::exp(-u / kRelaxTauS) - end) / (1.0 - end);
  const double kick = std::min(kKickS, 0.5 * diastole);
  if (tau > d - kick) {
    const double s = std::sin(kGenPi * (tau - (d - kick)) / kick);
    y += kKickFraction * s * s;
  }
  return y;
}

}  // namespace

MotionTrace GenerateRealisticHeartTrace(const RealisticHeartOptions& o, MotionTrace* truth) {
  const bool ok =
      GenFinite(o.duration_s) && o.duration_s > 0.0 && o.duration_s <= 3600.0 &&
      GenFinite(o.sample_rate_hz) && o.sample_rate_hz > 0.0 && o.sample_rate_hz <= 10000.0 &&
      GenFinite(o.heart_bpm) && o.heart_bpm >= 20.0 && o.heart_bpm <= 250.0 &&
      GenFinite(o.hrv_bpm) && o.hrv_bpm >= 0.0 && GenFinite(o.rsa_bpm) && o.rsa_bpm >= 0.0 &&
      GenFinite(o.rate_step_bpm) && GenFinite(o.rate_step_at_s) &&
      GenFinite(o.rate_drift_bpm_per_min) && o.ectopic_probability >= 0.0 &&
      o.ectopic_probability <= 0.5 && GenFinite(o.amplitude_mm) && o.amplitude_mm >= 0.0 &&
      GenFinite(o.breathing_hz) && o.breathing_hz > 0.0 && GenFinite(o.breathing_mm) &&
      o.breathing_mm >= 0.0 && o.breathing_modulation >= 0.0 && o.breathing_modulation < 1.0 &&
      GenFinite(o.noise_mm) && o.noise_mm >= 0.0 && GenFinite(o.noise_dof) && o.noise_dof > 0.0 &&
      o.outlier_probability >= 0.0 && o.outlier_probability <= 1.0 && GenFinite(o.outlier_mm) &&
      o.drop_probability >= 0.0 && o.drop_probability < 1.0 && o.burst_probability >= 0.0 &&
      o.burst_probability < 1.0;
  if (!ok) {
    throw std::invalid_argument(
        "realistic heart trace: duration (0, 3600] s, sample rate (0, 10000] Hz, heart rate "
        "[20, 250] bpm, ectopic probability [0, 0.5], breathing modulation [0, 1), drop and "
        "outlier probabilities in [0, 1) and every amplitude, noise and rate finite and >= 0");
  }
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);

  // Breathing: a phase whose rate changes breath to breath (±15 %).
  const double end_s = o.duration_s + 2.0;
  std::vector<double> breath_start{0.0};
  std::vector<double> breath_len;
  while (breath_start.back() < end_s) {
    breath_len.push_back((1.0 + 0.15 * (2.0 * uniform(rng) - 1.0)) / o.breathing_hz);
    breath_start.push_back(breath_start.back() + breath_len.back());
  }
  auto breath_phase = [&](double t) {
    const auto it = std::upper_bound(breath_start.begin(), breath_start.end(), t);
    const auto i =
        static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - breath_start.begin() - 1, 0));
    return 2.0 * kGenPi * (static_cast<double>(i) + (t - breath_start[i]) / breath_len[i]);
  };

  // Beats: RR intervals from the instantaneous rate; ectopics with compensatory pauses.
  std::vector<GenBeat> beats;
  double t = -1.5;  // start before 0 so the trace opens mid-rhythm
  double wander = 0.0;
  while (t < end_s) {
    double bpm = o.heart_bpm + wander + o.rsa_bpm * std::sin(breath_phase(std::max(t, 0.0))) +
                 o.rate_drift_bpm_per_min * t / 60.0 +
                 (t >= o.rate_step_at_s ? o.rate_step_bpm : 0.0);
    bpm = std::clamp(bpm, 25.0, 240.0);
    const double rr = 60.0 / bpm;
    if (uniform(rng) < o.ectopic_probability) {
      beats.push_back({t, kPrematureFraction * rr, kEctopicStrength});
      beats.push_back(
          {t + kPrematureFraction * rr, (2.0 - kPrematureFraction) * rr, kPostEctopicStrength});
      t += 2.0 * rr;
    } else {
      beats.push_back({t, rr, 1.0});
      t += rr;
    }
    const double decay = std::exp(-rr / kWanderTauS);
    wander = wander * decay + o.hrv_bpm * std::sqrt(1.0 - decay * decay) * normal(rng);
  }

  std::student_t_distribution<double> student(o.noise_dof);
  MotionTrace out;
  out.source = "realistic heart trace (seed " + std::to_string(o.seed) + ")";
  out.column = "position";
  if (truth != nullptr) {
    *truth = MotionTrace{};
    truth->source = out.source;
    truth->column = "truth";
  }
  const auto n = static_cast<std::size_t>(std::floor(o.duration_s * o.sample_rate_hz)) + 1;
  std::size_t beat = 0;
  int burst_left = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double ti = static_cast<double>(i) / o.sample_rate_hz;
    while (beat + 1 < beats.size() && beats[beat + 1].start_s <= ti) ++beat;
    const GenBeat& b = beats[beat];
    const double phi = breath_phase(ti);
    const double modulation = 1.0 + o.breathing_modulation * std::sin(phi + 0.8);
    const double clean = o.amplitude_mm * b.strength * modulation *
                             (BeatShape(ti - b.start_s, b.duration_s) - 0.35) +
                         0.5 * o.breathing_mm * std::sin(phi);
    if (truth != nullptr) {
      truth->t_s.push_back(ti);
      truth->position_mm.push_back(clean);
    }
    double z = clean + o.noise_mm * student(rng);
    if (uniform(rng) < o.outlier_probability)
      z += (uniform(rng) < 0.5 ? -1.0 : 1.0) * o.outlier_mm * (0.5 + 0.5 * uniform(rng));
    // Drops (the first and last samples are always kept).
    bool drop = false;
    if (burst_left > 0) {
      --burst_left;
      drop = true;
    } else if (uniform(rng) < o.burst_probability) {
      burst_left = 2 + static_cast<int>(uniform(rng) * 6.0);
      drop = true;
    } else if (uniform(rng) < o.drop_probability) {
      drop = true;
    }
    if (drop && i > 0 && i + 1 < n) continue;
    out.t_s.push_back(ti);
    out.position_mm.push_back(z);
  }
  return out;
}

std::vector<std::string> RealisticHeartClasses() {
  return {"regular", "ectopic", "rate_steps", "breathing", "noisy", "sparse", "fast"};
}

RealisticHeartOptions RealisticHeartClass(const std::string& name, std::uint64_t seed) {
  RealisticHeartOptions o;
  o.seed = seed;
  if (name == "regular") {
  } else if (name == "ectopic") {
    o.heart_bpm = 66.0;
    o.ectopic_probability = 0.12;
  } else if (name == "rate_steps") {
    o.heart_bpm = 62.0;
    o.rate_step_bpm = 30.0;
    o.rate_step_at_s = 14.0;
    o.rate_drift_bpm_per_min = -10.0;
  } else if (name == "breathing") {
    o.breathing_hz = 0.3;
    o.breathing_mm = 4.0;
    o.breathing_modulation = 0.3;
    o.rsa_bpm = 4.0;
  } else if (name == "noisy") {
    o.noise_mm = 0.4;
    o.noise_dof = 2.5;
    o.outlier_probability = 0.03;
  } else if (name == "sparse") {
    o.sample_rate_hz = 20.0;
    o.drop_probability = 0.08;
    o.burst_probability = 0.01;
  } else if (name == "fast") {
    o.heart_bpm = 125.0;
    o.sample_rate_hz = 30.0;
    o.amplitude_mm = 6.0;
  } else {
    std::string known;
    for (const auto& c : RealisticHeartClasses()) known += (known.empty() ? "" : ", ") + c;
    throw std::invalid_argument("realistic heart trace: unknown class '" + name +
                                "' (known: " + known + ")");
  }
  return o;
}

}  // namespace echoservo::estimation
