// A synthetic tracking run with known truth, for the report tests: the target moves with a
// heartbeat (fundamental and second harmonic along one axis, the fundamental with another
// phase along a second) plus a slow breathing drift along a third; the catheter tip is the
// target plus a constant offset, so the true tip-to-target error is |tip_offset_mm| at every
// instant. The EM tracker sees the tip in its own frame (image_to_em = em_to_image⁻¹) on its
// own clock (t_em = t − em_clock_offset_s), starting before and ending after the volumes.
// WriteSyntheticRun writes it as a RUN directory (formats/run_record.h). Units: mm, s.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <numbers>
#include <random>
#include <set>
#include <vector>

#include "formats/em_log.h"
#include "formats/run_record.h"

namespace echoservo::testing {

struct SyntheticRun {
  double duration_s = 20.0;
  double volume_rate_hz = 20.0;
  double em_rate_hz = 100.0;
  double truth_rate_hz = 200.0;
  double heart_rate_hz = 1.2;
  bool write_heart_rate = true;
  bool write_truth = true;
  double em_lead_s = 0.3;  // the EM log starts this long before the first volume
  // Motion amplitudes along the three axes (heartbeat, heartbeat at another phase, breath).
  Eigen::Vector3d amplitude_mm{10.0, 6.0, 4.0};
  double breathing_hz = 0.23;
  Eigen::Vector3d centre_mm{20.0, -15.0, 60.0};
  Eigen::Vector3d tip_offset_mm{0.6, -0.8, 0.5};  // tip − target
  Eigen::Isometry3d em_to_image = [] {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.linear() = (Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(-0.4, Eigen::Vector3d::UnitX()) *
                  Eigen::AngleAxisd(0.25, Eigen::Vector3d::UnitY()))
                     .toRotationMatrix();
    t.translation() = Eigen::Vector3d(-120.0, 35.0, -210.0);
    return t;
  }();
  double em_clock_offset_s = -1000.25;   // t_pipeline = t_em + offset
  double em_noise_mm = 0.0;              // per axis
  double image_noise_mm = 0.0;           // per axis, on the tracked tip and target
  std::size_t em_dropout_every = 0;      // every k-th EM sample MISSING (0: none)
  std::set<std::size_t> not_found;       // volumes without a target
  std::size_t gap_from = 0, gap_to = 0;  // volumes [from, to) never processed
  std::size_t latency_rows = 100;        // latency.csv: row i has (i + 1) ms
  unsigned seed = 7;

  Eigen::Vector3d TargetAt(double t) const {
    const double phi = 2.0 * std::numbers::pi * heart_rate_hz * t;
    return centre_mm +
           Eigen::Vector3d(amplitude_mm[0] * (std::sin(phi) + 0.3 * std::sin(2.0 * phi + 0.5)),
                           amplitude_mm[1] * std::sin(phi + 1.1),
                           amplitude_mm[2] * std::sin(2.0 * std::numbers::pi * breathing_hz * t));
  }
  Eigen::Vector3d TipAt(double t) const { return TargetAt(t) + tip_offset_mm; }
  // An upper bound of |d²tip/dt²| (mm/s²).
  double MaxAccelerationMmS2() const {
    const double w = 2.0 * std::numbers::pi * heart_rate_hz;
    const double b = 2.0 * std::numbers::pi * breathing_hz;
    return std::sqrt(std::pow(amplitude_mm[0] * (w * w + 0.3 * 4.0 * w * w), 2) +
                     std::pow(amplitude_mm[1] * w * w, 2) + std::pow(amplitude_mm[2] * b * b, 2));
  }
  std::size_t Volumes() const {
    return static_cast<std::size_t>(std::floor(duration_s * volume_rate_hz));
  }
  double VolumeTime(std::size_t i) const { return static_cast<double>(i) / volume_rate_hz; }

  // EM samples on the EM clock, in the EM frame.
  std::vector<formats::EmSample> EmSamples() const {
    std::mt19937 rng(seed + 1);
    std::normal_distribution<double> noise(0.0, 1.0);
    const Eigen::Isometry3d image_to_em = em_to_image.inverse();
    std::vector<formats::EmSample> out;
    const double t0 = -em_lead_s, t1 = duration_s + em_lead_s;
    for (std::size_t k = 0;; ++k) {
      const double t = t0 + static_cast<double>(k) / em_rate_hz;
      if (t > t1) break;
      formats::EmSample s;
      s.t_s = t - em_clock_offset_s;
      s.valid = em_dropout_every == 0 || k % em_dropout_every != 0;
      const Eigen::Vector3d n(noise(rng), noise(rng), noise(rng));
      if (s.valid) s.position_mm = image_to_em * TipAt(t) + em_noise_mm * n;
      out.push_back(s);
    }
    return out;
  }

  // The tracked volumes (targets.csv rows).
  std::vector<formats::TargetRecord> Targets() const {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    std::vector<formats::TargetRecord> out;
    for (std::size_t i = 0; i < Volumes(); ++i) {
      const Eigen::Vector3d n1(noise(rng), noise(rng), noise(rng));
      const Eigen::Vector3d n2(noise(rng), noise(rng), noise(rng));
      if (i >= gap_from && i < gap_to) continue;
      const double t = VolumeTime(i);
      formats::TargetRecord r;
      r.acquired_s = t;
      r.arrived_s = t + 0.030;
      r.published_s = t + 0.042;
      r.found = !not_found.contains(i);
      r.target_mm = TargetAt(t) + image_noise_mm * n1;
      r.tip_mm = TipAt(t) + image_noise_mm * n2;
      r.axis = Eigen::Vector3d::UnitZ();
      r.confidence = 0.9;
      out.push_back(r);
    }
    return out;
  }
};

inline void WriteSyntheticRun(const SyntheticRun& s, const std::filesystem::path& dir) {
  formats::RunInfo info;
  if (s.write_heart_rate) info.heart_rate_hz = s.heart_rate_hz;
  info.notes = "synthetic run (tests/test_util/synthetic_run.h)";
  formats::RunWriter w(dir, info);
  std::size_t row = 0;
  for (const formats::TargetRecord& r : s.Targets()) {
    w.AddTarget(r);
    if (row < s.latency_rows) {
      w.AddLatency({r.arrived_s, r.arrived_s + 1e-3 * static_cast<double>(row + 1)});
    }
    ++row;
  }
  for (const formats::EmSample& e : s.EmSamples()) w.AddEm(e);
  if (s.write_truth) {
    for (std::size_t k = 0;; ++k) {
      const double t = static_cast<double>(k) / s.truth_rate_hz;
      if (t > s.duration_s) break;
      w.AddTruth({t, s.TargetAt(t), s.TipAt(t)});
    }
  }
  for (std::size_t k = 0; k < 200; ++k) {
    const double t = 0.1 * static_cast<double>(k);
    w.AddServo(
        {t, k < 20 ? "hold" : "track", s.TipAt(t).x(), 0.9 * s.TipAt(t).x(), s.TipAt(t).x(), 0.0});
  }
}

}  // namespace echoservo::testing
