#include "estimation/heartbeat_ekf.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "estimation/harmonic_fit.h"

namespace echoservo::estimation {
namespace {

// The fewest measurements a (re)initialisation fits: twice the parameters of the largest
// model it may fit (2 per harmonic, the offset and a cubic trend).
std::size_t MinInitSamples(const HeartbeatEkfOptions& o) {
  const int h = o.harmonics > 0 ? o.harmonics : o.max_harmonics;
  return static_cast<std::size_t>(2 * (2 * h + 4));
}

constexpr double kNoiseFloorMm = 0.02;
constexpr double kNoiseAdaptation = 0.02;      // ~50 measurements (2 s at 25 vol/s)
constexpr int kInitTrendOrder = 3;             // cubic: slow respiration within the window
constexpr double kChoiceSplit = 0.6;           // harmonic choice: initialise on 60 %, score 40 %
constexpr double kMinOffsetRateQ = 0.3;        // mm/s/√s: the offset-rate intensity's floor
constexpr double kInitialOffsetRateVar = 1.0;  // (mm/s)²: the offset rate's prior
constexpr double kMinRejectedSpanS = 0.15;     // lost: rejections spanning at least this
constexpr double kRateCheckS = 1.0;            // the window's fundamental checked this often
constexpr double kRateDisagreement = 0.35;     // |filter / fundamental − 1| beyond: re-acquire

bool Positive(double v) { return std::isfinite(v) && v > 0.0; }

}  // namespace

HeartbeatEkf::HeartbeatEkf(HeartbeatEkfOptions options) : o_(options) {
  // The tunable parameters' bounds (params above), then what only combinations say.
  constexpr std::string_view kOwner = "heartbeat EKF";
  params::kHarmonics.Check(o_.harmonics, kOwner);
  params::kMaxHarmonics.Check(o_.max_harmonics, kOwner);
  params::kInitWindowS.Check(o_.init_window_s, kOwner);
  params::kNoiseMm.Check(o_.noise_mm, kOwner);
  params::kCoefficientQMm.Check(o_.coefficient_q_mm, kOwner);
  params::kOffsetQMm.Check(o_.offset_q_mm, kOwner);
  params::kRateQRadS.Check(o_.rate_q_rad_s, kOwner);
  params::kPhaseQRad.Check(o_.phase_q_rad, kOwner);
  params::kGateSigma.Check(o_.gate_sigma, kOwner);
  const bool ok =
      o_.harmonics >= 0 && o_.harmonics <= kMaxHarmonics && o_.max_harmonics >= 1 &&
      o_.max_harmonics <= kMaxHarmonics && Positive(o_.min_rate_hz) &&
      o_.max_rate_hz > o_.min_rate_hz && Positive(o_.init_window_s) && std::isfinite(o_.noise_mm) &&
      o_.noise_mm >= 0.0 && Positive(o_.coefficient_q_mm) && Positive(o_.offset_q_mm) &&
      std::isfinite(o_.offset_rate_q_mm_s) && o_.offset_rate_q_mm_s >= 0.0 &&
      Positive(o_.rate_q_rad_s) && Positive(o_.phase_q_rad) && Positive(o_.gate_sigma) &&
      o_.max_rejections >= 1 && Positive(o_.max_phase_sd_rad) && std::isfinite(o_.horizon_s) &&
      o_.horizon_s >= 0.0 && Positive(o_.band_min_hz) && o_.band_max_hz > o_.band_min_hz &&
      std::isfinite(o_.band_max_hz) && o_.reacquire_nis > 1.0 && std::isfinite(o_.reacquire_nis) &&
      o_.reacquire_fraction > 0.0 && o_.reacquire_fraction < 1.0 && Positive(o_.reacquire_beats);
  if (!ok) {
    throw std::invalid_argument(
        "heartbeat EKF: harmonics must be in [0, 12] (0: automatic), rates 0 < min < max, and "
        "every noise, gate and window positive, a rate band 0 < band_min_hz < band_max_hz, "
        "reacquire_nis > 1, reacquire_fraction in (0, 1) and reacquire_beats > 0");
  }
  cooldown_s_ = o_.init_window_s;
  if (o_.init_window_s * o_.min_rate_hz < 1.0) {
    throw std::invalid_argument("heartbeat EKF: the initialisation window (" +
                                std::to_string(o_.init_window_s) +
                                " s) must hold at least one beat at the lowest rate");
  }
}

int HeartbeatEkf::StateSize() const { return FirstCoefficient() + 1 + 2 * (harmonics_ - 1) + 2; }

double HeartbeatEkf::rate_hz() const { return initialised_ ? x_(PhaseIndex() + 1) / kTwoPi : 0.0; }

double HeartbeatEkf::phase_sd_rad() const {
  return initialised_ ? std::sqrt(std::max(p_(PhaseIndex(), PhaseIndex()), 0.0)) : 0.0;
}

int HeartbeatEkf::ChooseHarmonics() const {
  // Filters with 1..max harmonics, each initialised on the first part of the buffer,
  // predict the rest one measurement ahead; the smallest squared error wins.
  const double split_s = std::max(kChoiceSplit * o_.init_window_s, 1.0 / o_.min_rate_hz);
  std::vector<double> scores;
  for (int n = 1; n <= o_.max_harmonics; ++n) {
    HeartbeatEkfOptions sub = o_;
    sub.harmonics = n;
    sub.respiration = respiration_ ? Respiration::kOn : Respiration::kOff;  // decided already
    sub.offset_rate_q_mm_s = offset_rate_q_mm_s_;
    sub.init_window_s = split_s;
    HeartbeatEkf filter(sub);
    double ss = 0.0;
    try {
      for (const auto& [t, z] : buffer_) {
        if (filter.initialised()) ss += std::pow(z - filter.Predict(t), 2);
        filter.Process(t, z);
      }
    } catch (const std::invalid_argument&) {
      break;  // too many harmonics for this window or sampling rate
    }
    // A count that loses the phase within the window is no candidate (its zero-order
    // hold while re-initialising would score instead).
    const bool held = filter.initialised() && filter.initialisations() == 1;
    scores.push_back(held ? ss : std::numeric_limits<double>::infinity());
  }
  // The fewest harmonics within (0.01 mm)² a sample of the best (ties on clean data).
  const double best = *std::min_element(scores.begin(), scores.end());
  if (!std::isfinite(best)) return o_.max_harmonics;  // none held: the most flexible shape
  const double slack = 1e-4 * static_cast<double>(buffer_.size());
  for (std::size_t i = 0; i < scores.size(); ++i) {
    if (scores[i] <= best + slack) return static_cast<int>(i) + 1;
  }
  return 1;
}

void HeartbeatEkf::ChooseRespiration(const TrendEvidence& evidence) {
  respiration_ = o_.respiration == Respiration::kOn ||
                 (o_.respiration == Respiration::kAuto && evidence.Significant());
  // The offset rate follows white acceleration of intensity q = 2ā²τ (the equivalent
  // white noise of an acceleration of RMS ā and correlation time τ), with τ = T/(2π)
  // for the slowest oscillation a window of T seconds shows.
  offset_rate_q_mm_s_ =
      o_.offset_rate_q_mm_s > 0.0
          ? o_.offset_rate_q_mm_s
          : std::max(evidence.accel_rms_mm_s2 * std::sqrt(evidence.window_s / std::numbers::pi),
                     kMinOffsetRateQ);
}

void HeartbeatEkf::CheckRespiration() {
  const TrendEvidence evidence = trend_.Evidence();
  trend_.Reset(harmonics_, o_.init_window_s);
  ChooseRespiration(evidence);
  // Breathing persists: two windows in a row (repeated tests on white noise would
  // pass one now and then).
  const bool first = !trend_seen_;
  trend_seen_ = respiration_;
  if (!respiration_ || first) {
    respiration_ = false;
    return;
  }
  // Insert the offset rate after the offset: the trend's slope now, (1 mm/s)² prior.
  const int n = StateSize();  // with the new state
  Vector x(n);
  x(0) = x_(0);
  x(1) = evidence.drift_mm_s;
  x.tail(n - 2) = x_.tail(n - 2);
  Matrix p = Matrix::Zero(n, n);
  p(0, 0) = p_(0, 0);
  p.block(0, 2, 1, n - 2) = p_.block(0, 1, 1, n - 2);
  p.block(2, 0, n - 2, 1) = p_.block(1, 0, n - 2, 1);
  p.bottomRightCorner(n - 2, n - 2) = p_.bottomRightCorner(n - 2, n - 2);
  p(1, 1) = kInitialOffsetRateVar;
  x_ = x;
  p_ = p;
}

void HeartbeatEkf::Initialise(int keep_harmonics) {
  std::vector<double> t;
  std::vector<double> z;
  for (const auto& [ti, zi] : buffer_) {
    t.push_back(ti);
    z.push_back(zi);
  }
  // The rate from a search with its own (BIC) harmonic count, which resists sub-harmonics;
  // the coefficients at the filter's count.
  HarmonicFitOptions fo;
  fo.min_rate_hz = o_.min_rate_hz;
  fo.max_rate_hz = o_.max_rate_hz;
  fo.max_harmonics = o_.max_harmonics;
  fo.trend_order = kInitTrendOrder;
  const HarmonicFit search = FitHarmonics(t.data(), z.data(), t.size(), t.back(), fo);
  // The search's rate unless the window's significant fundamental (which cannot settle on
  // a sub-harmonic or a harmonic) is more than kRateDisagreement away: a lock onto a
  // multiple or fraction of the beat. Within that, the search's fit is the finer estimate
  // (measured: taking the fundamental's always cost 0.24 → 0.37 of the hold on regular).
  const HeartRateEstimate fundamental = WindowHeartRate(t, z);
  const double searched = search.motion.frequency_hz;
  const double rate_hz =
      fundamental.significant && std::abs(searched / fundamental.rate_hz - 1.0) > kRateDisagreement
          ? fundamental.rate_hz
          : searched;
  // The slow-trend test at the searched rate and harmonic count.
  SlowTrendWindow window;
  window.Reset(search.harmonics, o_.init_window_s);
  for (std::size_t i = 0; i < t.size(); ++i)
    window.Add(t[i], kTwoPi * rate_hz * (t[i] - t.back()), z[i]);
  ChooseRespiration(window.Evidence());
  const int count = keep_harmonics > 0 ? keep_harmonics
                    : o_.harmonics > 0 ? o_.harmonics
                                       : ChooseHarmonics();
  const HarmonicFit fit =
      FitHarmonicsAtRate(t.data(), z.data(), t.size(), t.front(), rate_hz, count, kInitTrendOrder);
  harmonics_ = fit.harmonics;
  noise_mm_ = o_.noise_mm > 0.0 ? o_.noise_mm : std::max(fit.noise_mm, kNoiseFloorMm);

  const int n = StateSize();
  const int c0 = FirstCoefficient();
  x_.setZero(n);
  p_.setZero(n, n);
  x_(0) = fit.motion.offset_mm;
  if (respiration_) x_(1) = fit.motion.drift_mm_s;
  x_(c0) = fit.motion.cos_mm[0];
  for (int k = 2; k <= harmonics_; ++k) {
    x_(c0 + 2 * k - 3) = fit.motion.cos_mm[static_cast<std::size_t>(k - 1)];
    x_(c0 + 2 * k - 2) = fit.motion.sin_mm[static_cast<std::size_t>(k - 1)];
  }
  x_(PhaseIndex()) = fit.motion.phase0_rad;
  x_(PhaseIndex() + 1) = kTwoPi * fit.motion.frequency_hz;

  // Initial uncertainty: least-squares variances (≈ 2σ²/n per coefficient), inflated
  // fourfold for the model's own approximation, and a broad phase and rate.
  const double m = static_cast<double>(t.size());
  const double coef_var = 8.0 * noise_mm_ * noise_mm_ / m + 0.01;
  for (int i = 0; i < PhaseIndex(); ++i) p_(i, i) = coef_var;
  if (respiration_) p_(1, 1) = kInitialOffsetRateVar;
  const double amp = std::max(std::abs(x_(c0)), 0.1);
  p_(PhaseIndex(), PhaseIndex()) =
      std::pow(std::max(0.05, 2.0 * noise_mm_ / amp / std::sqrt(m)), 2);
  p_(PhaseIndex() + 1, PhaseIndex() + 1) = std::pow(kTwoPi * 0.05, 2);

  // Warm start: the batch fit holds one rate over the window, while the heart rate
  // changes within it; filtering the window from its first sample on leaves the phase
  // and rate of its end, where prediction starts.
  t_ = t.front();
  for (std::size_t i = 1; i < t.size(); ++i) Correct(t[i], z[i]);
  initialised_ = true;
  ++initialisations_;
  consecutive_rejections_ = 0;
  buffer_.clear();
  recent_.clear();
  trend_.Reset(harmonics_, o_.init_window_s);
  trend_seen_ = false;
  // The fitted window's range bounds the predictions until Watch takes the newest window's.
  window_lo_mm_ = *std::min_element(z.begin(), z.end());
  window_hi_mm_ = *std::max_element(z.begin(), z.end());
  nis_mean_ = 0.0;
  since_init_s_ = 0.0;
  out_of_band_ = false;
}

HeartRateEstimate HeartbeatEkf::WindowHeartRate(const std::vector<double>& t,
                                                const std::vector<double>& z) const {
  if (t.size() < 16) return {};
  HeartRateOptions ho;
  ho.min_hz = o_.min_rate_hz;
  ho.max_hz = o_.max_rate_hz;
  ho.max_analysis_hz = std::max(ho.max_analysis_hz, 2.5 * ho.max_hz);
  return EstimateHeartRate(t.data(), z.data(), t.size(), ho);
}

void HeartbeatEkf::Watch(double dt_s, double nis, bool out_of_band) {
  const double rate = std::max(rate_hz(), band_min_hz());
  since_init_s_ += dt_s;
  const double alpha = std::min(1.0, dt_s * rate / o_.reacquire_beats);
  // The fraction of large innovations (ν²/S above reacquire_nis): robust to single
  // outliers and ectopic beats, which a mean of ν²/S is not.
  nis_mean_ += alpha * ((nis > o_.reacquire_nis ? 1.0 : 0.0) - nis_mean_);
  // Large innovations re-acquire after reacquire_beats beats, and no sooner than a cooldown
  // that doubles with each such re-acquisition (up to 8 windows: irregular rhythms that no
  // refit helps do not refit on every beat) and returns to one window once a cooldown
  // passes without one.
  const bool settled = since_init_s_ * rate >= o_.reacquire_beats && since_init_s_ >= cooldown_s_;
  bool diverged = settled && nis_mean_ > o_.reacquire_fraction;
  // The data's own fundamental over the window (estimation/heart_rate.h) is significant
  // and more than 15 % from the filter's rate: a sub-harmonic or harmonic lock (after a
  // jump the filter may settle at half or twice the new rate while the adaptive noise
  // keeps ν²/S small) or a lost rate. Checked once a second (~0.1 ms for 100 samples).
  since_rate_check_s_ += dt_s;
  // Strong evidence of its own: it waits only for a window wholly after the last
  // (re)initialisation, not for the cooldown.
  if (!diverged && since_init_s_ >= o_.init_window_s && since_rate_check_s_ >= kRateCheckS) {
    since_rate_check_s_ = 0.0;
    std::vector<double> wt, wz;
    for (const auto& [ti, zi] : window_) {
      wt.push_back(ti);
      wz.push_back(zi);
    }
    const HeartRateEstimate e = WindowHeartRate(wt, wz);
    diverged = e.significant && std::abs(rate_hz() / e.rate_hz - 1.0) > kRateDisagreement;
  }
  if (settled && !diverged) cooldown_s_ = o_.init_window_s;
  // A state far outside what the window shows (an ill-conditioned fit or a run-away offset
  // rate) has diverged too: the model's excursion or a second's drift beyond 3× the
  // window's range (+1 mm).
  double lo = window_.front().second;
  double hi = lo;
  for (const auto& [t, z] : window_) {
    lo = std::min(lo, z);
    hi = std::max(hi, z);
  }
  window_lo_mm_ = lo;
  window_hi_mm_ = hi;
  if (!diverged) {
    const double bound = 3.0 * (hi - lo) + 1.0;
    double excursion = std::abs(x_(0) - 0.5 * (lo + hi));
    for (int i = FirstCoefficient(); i < PhaseIndex(); ++i) excursion += std::abs(x_(i));
    const double drift = respiration_ ? std::abs(x_(1)) : 0.0;
    diverged = !(excursion <= bound && drift <= bound);
  }
  // The clamp keeps ω in the band at once; a refit waits for the cooldown too.
  if (!((out_of_band && since_init_s_ >= cooldown_s_) || diverged)) return;
  // Re-acquire on the newest window when it spans the initialisation window (else the
  // clamped rate carries on until it does).
  if (window_.size() < MinInitSamples(o_) ||
      window_.back().first - window_.front().first < o_.init_window_s)
    return;
  buffer_.assign(window_.begin(), window_.end());
  ++reacquisitions_;
  cooldown_s_ = std::min(2.0 * cooldown_s_, 8.0 * o_.init_window_s);
  Initialise(harmonics_);
}

void HeartbeatEkf::TimeUpdate(double dt) {
  if (dt <= 0.0) return;
  const int n = StateSize();
  const int th = PhaseIndex();
  const int om = th + 1;
  // x ← F x
  x_(th) += x_(om) * dt;
  if (respiration_) x_(0) += x_(1) * dt;
  // P ← F P Fᵀ: F = I + dt·(e_θ e_ωᵀ [+ e_c e_ċᵀ]); rows then columns.
  p_.row(th) += dt * p_.row(om);
  if (respiration_) p_.row(0) += dt * p_.row(1);
  p_.col(th) += dt * p_.col(om);
  if (respiration_) p_.col(0) += dt * p_.col(1);
  // + Q
  const double qc = o_.coefficient_q_mm * o_.coefficient_q_mm * dt;
  for (int i = FirstCoefficient(); i < th; ++i) p_(i, i) += qc;
  const double qo = o_.offset_q_mm * o_.offset_q_mm;
  p_(0, 0) += qo * dt;
  if (respiration_) {
    const double qr = offset_rate_q_mm_s_ * offset_rate_q_mm_s_;
    p_(0, 0) += qr * dt * dt * dt / 3.0;
    p_(0, 1) += qr * dt * dt / 2.0;
    p_(1, 0) += qr * dt * dt / 2.0;
    p_(1, 1) += qr * dt;
  }
  const double qw = o_.rate_q_rad_s * o_.rate_q_rad_s;
  const double qp = o_.phase_q_rad * o_.phase_q_rad;
  p_(th, th) += qw * dt * dt * dt / 3.0 + qp * dt;
  p_(th, om) += qw * dt * dt / 2.0;
  p_(om, th) += qw * dt * dt / 2.0;
  p_(om, om) += qw * dt;
  (void)n;
}

double HeartbeatEkf::ShapeAt(double theta, Vector* h) const {
  const int c0 = FirstCoefficient();
  const double c1 = std::cos(theta);
  const double s1 = std::sin(theta);
  double z = x_(0) + x_(c0) * c1;
  double dtheta = -x_(c0) * s1;
  if (h != nullptr) {
    h->setZero(StateSize());
    (*h)(0) = 1.0;
    (*h)(c0) = c1;
  }
  double ck = c1;
  double sk = s1;
  for (int k = 2; k <= harmonics_; ++k) {
    const double next = ck * c1 - sk * s1;
    sk = sk * c1 + ck * s1;
    ck = next;
    const double a = x_(c0 + 2 * k - 3);
    const double b = x_(c0 + 2 * k - 2);
    z += a * ck + b * sk;
    if (h != nullptr) {
      dtheta += k * (-a * sk + b * ck);
      (*h)(c0 + 2 * k - 3) = ck;
      (*h)(c0 + 2 * k - 2) = sk;
    }
  }
  if (h != nullptr) (*h)(PhaseIndex()) = dtheta;
  return z;
}

UpdateResult HeartbeatEkf::Process(double t_s, double z) {
  if (!std::isfinite(t_s) || !std::isfinite(z)) {
    throw std::invalid_argument("heartbeat EKF: a measurement or its time is NaN or infinite");
  }
  if (any_ && !(t_s > (initialised_ ? t_ : buffer_.empty() ? -INFINITY : buffer_.back().first))) {
    throw std::invalid_argument("heartbeat EKF: measurement times must be strictly increasing");
  }
  any_ = true;
  last_mm_ = z;
  window_.emplace_back(t_s, z);
  while (window_.size() > 2 && window_.back().first - window_[1].first >= o_.init_window_s)
    window_.pop_front();
  if (!initialised_) {
    buffer_.emplace_back(t_s, z);
    // Sparse data (many frames lost) may span the window with too few samples to fit (and
    // alias the heartbeat): wait for enough; older samples go once enough newer ones still
    // span the window (a sparse start does not stay in the fit).
    while (buffer_.size() > MinInitSamples(o_) &&
           buffer_.back().first - buffer_[1].first >= o_.init_window_s)
      buffer_.pop_front();
    if (buffer_.back().first - buffer_.front().first < o_.init_window_s ||
        buffer_.size() < MinInitSamples(o_))
      return UpdateResult::kBuffering;
    Initialise();
    return UpdateResult::kInitialised;
  }

  const double dt_s = t_s - t_;
  const UpdateResult result = Correct(t_s, z);
  if (result == UpdateResult::kLost) {  // coasted too long: phase unknown
    initialised_ = false;
    buffer_.assign(1, {t_s, z});
    return result;
  }
  if (result == UpdateResult::kRejected) {
    ++rejected_;
    recent_.emplace_back(t_s, z);
    // Lost after max_rejections in a row spanning kMinRejectedSpanS (at 25 Hz the count
    // decides; at 200 Hz five rejections are 20 ms of one beat's shape change, not a loss).
    if (++consecutive_rejections_ >= o_.max_rejections &&
        recent_.back().first - recent_.front().first >= kMinRejectedSpanS) {
      initialised_ = false;
      buffer_.assign(recent_.begin(), recent_.end());
      recent_.clear();
      return UpdateResult::kLost;
    }
    Watch(dt_s, last_nis_, out_of_band_);
    return result;
  }
  consecutive_rejections_ = 0;
  recent_.clear();
  ++accepted_;
  if (o_.respiration == Respiration::kAuto && !respiration_) {
    trend_.Add(t_s, x_(PhaseIndex()), z);
    if (trend_.span_s() >= o_.init_window_s) CheckRespiration();
  }
  Watch(dt_s, last_nis_, out_of_band_);
  return result;
}

UpdateResult HeartbeatEkf::Correct(double t_s, double z) {
  TimeUpdate(t_s - t_);
  t_ = t_s;
  if (phase_sd_rad() > o_.max_phase_sd_rad) return UpdateResult::kLost;
  Vector h;
  const double predicted = ShapeAt(x_(PhaseIndex()), &h);
  const Vector ph = p_ * h;
  const double s = h.dot(ph) + noise_mm_ * noise_mm_;
  const double nu = z - predicted;
  last_nis_ = nu * nu / s;
  out_of_band_ = false;
  if (nu * nu > o_.gate_sigma * o_.gate_sigma * s) return UpdateResult::kRejected;
  if (o_.noise_mm == 0.0) {
    // Innovation-based measurement noise: E[ν²] = HPHᵀ + R (exponential average).
    const double r = std::max(nu * nu - (s - noise_mm_ * noise_mm_), kNoiseFloorMm * kNoiseFloorMm);
    noise_mm_ = std::sqrt((1.0 - kNoiseAdaptation) * noise_mm_ * noise_mm_ + kNoiseAdaptation * r);
  }
  const Vector k = ph / s;
  x_ += k * nu;
  p_.noalias() -= k * ph.transpose();
  p_ = 0.5 * (p_ + p_.transpose()).eval();
  // The heart rate stays in its band: clamp ω (an update past the edge is a symptom of a
  // lost phase; the caller re-acquires).
  const int om = PhaseIndex() + 1;
  const double lo = kTwoPi * band_min_hz();
  const double hi = kTwoPi * band_max_hz();
  if (!(x_(om) >= lo && x_(om) <= hi)) {
    x_(om) = std::clamp(std::isfinite(x_(om)) ? x_(om) : lo, lo, hi);
    out_of_band_ = true;
  }
  return UpdateResult::kAccepted;
}

double HeartbeatEkf::Predict(double t_s) const {
  if (!initialised_) return last_mm_;
  const double dt = t_s - t_;
  double z = ShapeAt(x_(PhaseIndex()) + x_(PhaseIndex() + 1) * dt, nullptr);
  if (respiration_) z += x_(1) * dt;
  // Physically plausible: within the newest window's range ± half of it (+0.5 mm), whatever
  // the state (a refit on a window the model does not fit may be ill-conditioned until the
  // next measurement re-acquires).
  if (window_hi_mm_ >= window_lo_mm_) {
    const double margin = 0.5 * (window_hi_mm_ - window_lo_mm_) + 0.5;
    z = std::clamp(z, window_lo_mm_ - margin, window_hi_mm_ + margin);
  }
  return z;
}

FourierMotion HeartbeatEkf::Motion() const {
  FourierMotion m;
  if (!initialised_) {
    m.t0_s = buffer_.empty() ? 0.0 : buffer_.back().first;
    m.offset_mm = last_mm_;
    m.valid_until_s = m.t0_s;
    return m;
  }
  const int c0 = FirstCoefficient();
  const int th = PhaseIndex();
  m.t0_s = t_;
  m.phase0_rad = x_(th);
  m.frequency_hz = std::max(x_(th + 1) / kTwoPi, 1e-6);
  m.offset_mm = x_(0);
  m.drift_mm_s = respiration_ ? x_(1) : 0.0;
  m.cos_mm.push_back(x_(c0));
  m.sin_mm.push_back(0.0);
  for (int k = 2; k <= harmonics_; ++k) {
    m.cos_mm.push_back(x_(c0 + 2 * k - 3));
    m.sin_mm.push_back(x_(c0 + 2 * k - 2));
  }
  m.valid_until_s = t_ + o_.horizon_s;
  return m;
}

}  // namespace echoservo::estimation
