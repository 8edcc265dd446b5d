#include "estimation/motion_predictor.h"

#include <cmath>
#include <stdexcept>

namespace echoservo::estimation {

void LinearExtrapolation::Update(double t_s, double position_mm) {
  t_[0] = t_[1];
  x_[0] = x_[1];
  t_[1] = t_s;
  x_[1] = position_mm;
  if (count_ < 2) ++count_;
}

double LinearExtrapolation::Predict(double t_s) const {
  if (count_ < 2) return x_[1];
  return x_[1] + (x_[1] - x_[0]) / (t_[1] - t_[0]) * (t_s - t_[1]);
}

ConstantVelocityKf::ConstantVelocityKf(ConstantVelocityKfOptions options) : o_(options) {
  if (!(o_.accel_psd_mm2_s3 > 0.0 && std::isfinite(o_.accel_psd_mm2_s3) && o_.noise_mm > 0.0 &&
        std::isfinite(o_.noise_mm))) {
    throw std::invalid_argument("constant-velocity KF: q and the noise must be finite and > 0");
  }
}

void ConstantVelocityKf::Update(double t_s, double z) {
  const double r = o_.noise_mm * o_.noise_mm;
  if (!started_) {
    started_ = true;
    t_ = t_s;
    x_ = z;
    v_ = 0.0;
    pxx_ = r;
    pxv_ = 0.0;
    pvv_ = 1e4;  // (100 mm/s)²: the velocity is unknown
    return;
  }
  const double dt = t_s - t_;
  const double q = o_.accel_psd_mm2_s3;
  // Time update: F = [1 dt; 0 1], Q = q·[dt³/3 dt²/2; dt²/2 dt].
  x_ += v_ * dt;
  pxx_ += 2.0 * dt * pxv_ + dt * dt * pvv_ + q * dt * dt * dt / 3.0;
  pxv_ += dt * pvv_ + q * dt * dt / 2.0;
  pvv_ += q * dt;
  t_ = t_s;
  // Measurement update, H = [1 0].
  const double s = pxx_ + r;
  const double kx = pxx_ / s;
  const double kv = pxv_ / s;
  const double nu = z - x_;
  x_ += kx * nu;
  v_ += kv * nu;
  pvv_ -= kv * pxv_;
  pxv_ -= kv * pxx_;
  pxx_ -= kx * pxx_;
}

}  // namespace echoservo::estimation
