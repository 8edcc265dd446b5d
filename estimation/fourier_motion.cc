#include "estimation/fourier_motion.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace echoservo::estimation {

void FourierMotion::Validate() const {
  if (cos_mm.size() != sin_mm.size()) {
    throw std::invalid_argument("Fourier motion: cos and sin coefficient counts differ");
  }
  if (!(std::isfinite(frequency_hz) && frequency_hz > 0.0)) {
    throw std::invalid_argument("Fourier motion: frequency_hz must be finite and > 0");
  }
  auto finite = [](double v) { return std::isfinite(v); };
  bool ok = finite(t0_s) && finite(phase0_rad) && finite(offset_mm) && finite(drift_mm_s) &&
            !std::isnan(valid_until_s);
  for (std::size_t k = 0; k < cos_mm.size(); ++k) ok = ok && finite(cos_mm[k]) && finite(sin_mm[k]);
  if (!ok) throw std::invalid_argument("Fourier motion: non-finite coefficient or time");
}

MotionSample FourierMotion::Evaluate(double t_s) const {
  const double w = 2.0 * std::numbers::pi * frequency_hz;
  const double phase = w * (t_s - t0_s) + phase0_rad;
  const double c1 = std::cos(phase);
  const double s1 = std::sin(phase);
  double ck = c1;
  double sk = s1;
  MotionSample out{offset_mm + drift_mm_s * (t_s - t0_s), drift_mm_s, 0.0};
  for (std::size_t i = 0; i < cos_mm.size(); ++i) {
    const double k = static_cast<double>(i + 1);
    const double a = cos_mm[i];
    const double b = sin_mm[i];
    out.position_mm += a * ck + b * sk;
    out.velocity_mm_s += k * w * (-a * sk + b * ck);
    out.acceleration_mm_s2 -= k * k * w * w * (a * ck + b * sk);
    const double next_c = ck * c1 - sk * s1;
    sk = sk * c1 + ck * s1;
    ck = next_c;
  }
  return out;
}

FourierMotion FourierMotion::FromPeriodSamples(const std::vector<double>& samples, int harmonics,
                                               double frequency_hz) {
  const std::size_t n = samples.size();
  if (harmonics < 0 || n < static_cast<std::size_t>(2 * harmonics + 1)) {
    throw std::invalid_argument("Fourier motion: need at least 2N+1 samples for N harmonics");
  }
  FourierMotion m;
  m.frequency_hz = frequency_hz;
  double mean = 0.0;
  for (double v : samples) mean += v;
  m.offset_mm = mean / static_cast<double>(n);
  for (int k = 1; k <= harmonics; ++k) {
    double a = 0.0;
    double b = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double ph =
          2.0 * std::numbers::pi * k * static_cast<double>(i) / static_cast<double>(n);
      a += samples[i] * std::cos(ph);
      b += samples[i] * std::sin(ph);
    }
    m.cos_mm.push_back(2.0 * a / static_cast<double>(n));
    m.sin_mm.push_back(2.0 * b / static_cast<double>(n));
  }
  m.Validate();
  return m;
}

}  // namespace echoservo::estimation
