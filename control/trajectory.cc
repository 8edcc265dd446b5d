#include "control/trajectory.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

namespace echoservo::control {
namespace {

// Keyframes of one cardiac cycle (phase in [0, 1), normalised displacement towards
// the apex, 0 at end-diastole). Between keyframes the displacement follows a raised
// cosine, so each phase of the cycle starts and ends at rest.
struct Keyframe {
  double phase;
  double displacement;
};
constexpr std::array<Keyframe, 6> kMitralKeyframes = {{
    {0.00, 0.00},   // end-diastole (R wave)
    {0.36, 1.00},   // end of systole: annulus fully towards the apex
    {0.50, 0.25},   // end of rapid early-diastolic return (e')
    {0.80, 0.18},   // diastasis: slow drift
    {0.93, -0.02},  // atrial kick (a') overshoots slightly
    {1.00, 0.00},
}};

double MitralShape(double phase) {
  for (std::size_t i = 0; i + 1 < kMitralKeyframes.size(); ++i) {
    const Keyframe& a = kMitralKeyframes[i];
    const Keyframe& b = kMitralKeyframes[i + 1];
    if (phase >= a.phase && phase <= b.phase) {
      const double u = (phase - a.phase) / (b.phase - a.phase);
      return a.displacement +
             (b.displacement - a.displacement) * 0.5 * (1.0 - std::cos(std::numbers::pi * u));
    }
  }
  return 0.0;
}

}  // namespace

SineTrajectory::SineTrajectory(double amplitude_mm, double frequency_hz)
    : amplitude_mm_(amplitude_mm), frequency_hz_(frequency_hz) {
  if (!(std::isfinite(amplitude_mm) && amplitude_mm > 0.0 && std::isfinite(frequency_hz) &&
        frequency_hz > 0.0)) {
    throw std::invalid_argument("sine trajectory: amplitude and frequency must be finite and > 0");
  }
}

MotionSample SineTrajectory::Evaluate(double t_s) const {
  const double w = 2.0 * std::numbers::pi * frequency_hz_;
  const double s = std::sin(w * t_s);
  const double c = std::cos(w * t_s);
  return {amplitude_mm_ * s, amplitude_mm_ * w * c, -amplitude_mm_ * w * w * s};
}

MitralTrajectory::MitralTrajectory(MitralOptions options) {
  if (!(options.heart_rate_bpm >= 30.0 && options.heart_rate_bpm <= 200.0)) {
    throw std::invalid_argument("mitral trajectory: heart_rate_bpm must be in [30, 200]");
  }
  if (!(options.peak_to_peak_mm >= 1.0 && options.peak_to_peak_mm <= 40.0)) {
    throw std::invalid_argument("mitral trajectory: peak_to_peak_mm must be in [1, 40]");
  }
  if (options.harmonics < 1 || options.harmonics > 30) {
    throw std::invalid_argument("mitral trajectory: harmonics must be in [1, 30]");
  }
  constexpr int kSamples = 2048;
  std::vector<double> shape(kSamples);
  for (int i = 0; i < kSamples; ++i) shape[i] = MitralShape(static_cast<double>(i) / kSamples);
  motion_ = estimation::FourierMotion::FromPeriodSamples(shape, options.harmonics,
                                                         options.heart_rate_bpm / 60.0);
  // Scale the truncated series to the requested peak to peak, centred on zero.
  double lo = 1e9;
  double hi = -1e9;
  for (int i = 0; i < kSamples; ++i) {
    const double x = motion_.Position(static_cast<double>(i) / kSamples / motion_.frequency_hz);
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  }
  const double gain = options.peak_to_peak_mm / (hi - lo);
  // Motion towards the apex is negative (away from a catheter entering from the atrium).
  // The harmonic part spans [lo - offset, hi - offset]; after scaling by -gain, centre it.
  const double mid_harmonic = 0.5 * (lo + hi) - motion_.offset_mm;
  for (double& a : motion_.cos_mm) a *= -gain;
  for (double& b : motion_.sin_mm) b *= -gain;
  motion_.offset_mm = gain * mid_harmonic;
}

TriangleTrajectory::TriangleTrajectory(double amplitude_mm, double speed_mm_s)
    : amplitude_mm_(amplitude_mm), speed_mm_s_(speed_mm_s) {
  if (!(std::isfinite(amplitude_mm) && amplitude_mm > 0.0 && std::isfinite(speed_mm_s) &&
        speed_mm_s > 0.0)) {
    throw std::invalid_argument("triangle trajectory: amplitude and speed must be finite and > 0");
  }
}

MotionSample TriangleTrajectory::Evaluate(double t_s) const {
  const double a = amplitude_mm_;
  double u = std::fmod(t_s * speed_mm_s_, 4.0 * a);
  if (u < 0.0) u += 4.0 * a;
  if (u < a) return {u, speed_mm_s_, 0.0};
  if (u < 3.0 * a) return {2.0 * a - u, -speed_mm_s_, 0.0};
  return {u - 4.0 * a, speed_mm_s_, 0.0};
}

namespace {

std::vector<double> SpecNumbers(const std::string& spec, std::size_t first_colon) {
  std::vector<double> values;
  std::size_t start = first_colon + 1;
  while (start <= spec.size()) {
    const std::size_t end = std::min(spec.find(':', start), spec.size());
    const std::string field = spec.substr(start, end - start);
    std::size_t used = 0;
    double v = 0.0;
    try {
      v = std::stod(field, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (field.empty() || used != field.size() || !std::isfinite(v)) {
      throw std::invalid_argument("trajectory '" + spec + "': '" + field + "' is not a number");
    }
    values.push_back(v);
    start = end + 1;
  }
  return values;
}

}  // namespace

std::unique_ptr<Trajectory> MakeTrajectory(const std::string& spec) {
  const std::size_t colon = spec.find(':');
  const std::string kind = spec.substr(0, colon);
  const std::vector<double> args =
      colon == std::string::npos ? std::vector<double>{} : SpecNumbers(spec, colon);
  auto need = [&](std::size_t n, const char* form) {
    if (args.size() != n && !args.empty()) {
      throw std::invalid_argument("trajectory '" + spec + "': expected " + form);
    }
  };
  if (kind == "sine") {
    need(2, "sine:AMP_MM:FREQ_HZ");
    return args.empty() ? std::make_unique<SineTrajectory>(5.0, 1.0)
                        : std::make_unique<SineTrajectory>(args[0], args[1]);
  }
  if (kind == "triangle") {
    if (args.size() != 2)
      throw std::invalid_argument("trajectory '" + spec + "': expected triangle:AMP_MM:SPEED_MM_S");
    return std::make_unique<TriangleTrajectory>(args[0], args[1]);
  }
  if (kind == "mitral") {
    need(2, "mitral:BPM:P2P_MM");
    MitralOptions o;
    if (!args.empty()) {
      o.heart_rate_bpm = args[0];
      o.peak_to_peak_mm = args[1];
    }
    return std::make_unique<MitralTrajectory>(o);
  }
  throw std::invalid_argument(
      "unknown trajectory '" + spec +
      "' (expected sine, sine:A:F, triangle:A:V, mitral or mitral:BPM:P2P)");
}

}  // namespace echoservo::control
