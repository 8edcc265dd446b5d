// Predictors of target motion through the imaging delay: the interface shared by the
// heartbeat EKF (estimation/heartbeat_ekf.h) and the baselines it is measured against.
//
// A predictor receives measurements of the target position (mm along the catheter axis)
// time-stamped at acquisition (s), in time order, and predicts the position at any later
// time (typically the newest acquisition time plus the imaging latency). Baselines:
// zero-order hold (the newest measurement), linear extrapolation through the two newest
// measurements, and a constant-velocity Kalman filter (state position and velocity,
// white-noise acceleration of spectral density q mm²/s³, measurement noise σ mm).
#pragma once

#include <string>

namespace echoservo::estimation {

class MotionPredictor {
 public:
  virtual ~MotionPredictor() = default;
  virtual std::string name() const = 0;
  // t_s must increase from call to call.
  virtual void Update(double t_s, double position_mm) = 0;
  // Position at t_s (after the newest measurement); requires at least one Update.
  virtual double Predict(double t_s) const = 0;
};

class ZeroOrderHold final : public MotionPredictor {
 public:
  std::string name() const override { return "zero_order_hold"; }
  void Update(double, double position_mm) override { last_mm_ = position_mm; }
  double Predict(double) const override { return last_mm_; }

 private:
  double last_mm_ = 0.0;
};

class LinearExtrapolation final : public MotionPredictor {
 public:
  std::string name() const override { return "linear_extrapolation"; }
  void Update(double t_s, double position_mm) override;
  double Predict(double t_s) const override;

 private:
  int count_ = 0;
  double t_[2] = {0.0, 0.0};
  double x_[2] = {0.0, 0.0};
};

struct ConstantVelocityKfOptions {
  double accel_psd_mm2_s3 = 1e4;  // q: white-noise acceleration spectral density
  double noise_mm = 0.3;          // σ of a measurement
};

class ConstantVelocityKf final : public MotionPredictor {
 public:
  // Throws std::invalid_argument for non-positive q or σ.
  explicit ConstantVelocityKf(ConstantVelocityKfOptions options = {});
  std::string name() const override { return "constant_velocity_kf"; }
  void Update(double t_s, double position_mm) override;
  double Predict(double t_s) const override { return x_ + v_ * (t_s - t_); }

 private:
  ConstantVelocityKfOptions o_;
  bool started_ = false;
  double t_ = 0.0;
  double x_ = 0.0;
  double v_ = 0.0;
  double pxx_ = 0.0;
  double pxv_ = 0.0;
  double pvv_ = 0.0;
};

}  // namespace echoservo::estimation
