#include "imaging/sim/water_tank_sweep.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

#include "imaging/sim/simulated_scanner.h"

namespace echoservo::imaging::sim {
namespace {

void SweepRequire(double value, double lo, double hi, const char* name, bool open_lo = false) {
  if (!std::isfinite(value) || value < lo || value > hi || (open_lo && value == lo)) {
    throw std::invalid_argument(std::string("WaterTankSweepOptions: ") + name + " = " +
                                std::to_string(value) + " is outside " + (open_lo ? "(" : "[") +
                                std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
}

std::string SweepMatrixText(const Eigen::Matrix4d& m) {
  std::string text;
  char buf[32];
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      std::snprintf(buf, sizeof buf, "%.9g", m(r, c));
      text += (text.empty() ? "" : " ") + std::string(buf);
    }
  return text;
}

std::string SweepTimeText(double t) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6f", t);
  return buf;
}

}  // namespace

Eigen::Isometry3d WaterTankSweepOptions::DefaultTrackerFromWorld() {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()).matrix();
  t.translation() = Eigen::Vector3d(150.0, -30.0, 20.0);
  return t;
}

void WaterTankSweepOptions::Validate() const {
  SweepRequire(duration_s, 0, 600, "duration_s", true);
  SweepRequire(video_rate_hz, 0, 200, "video_rate_hz", true);
  SweepRequire(tracker_rate_hz, 0, 1000, "tracker_rate_hz", true);
  SweepRequire(tracker_lag_s, -5, 5, "tracker_lag_s");
  SweepRequire(start_s, -1e9, 1e9, "start_s");
  SweepRequire(amplitude_mm, 0, 40, "amplitude_mm", true);
  SweepRequire(period_s, 0.2, 60, "period_s");
  SweepRequire(bottom_depth_mm, 20, 100, "bottom_depth_mm");
  SweepRequire(tracker_noise_mm, 0, 5, "tracker_noise_mm");
  SweepRequire(width_px, 16, 1024, "width_px");
  SweepRequire(depth_px, 16, 2048, "depth_px");
  SweepRequire(range_mm, bottom_depth_mm + amplitude_mm, 300, "range_mm", true);
  // The probe stays in the water: 5 mm above the bottom, inside the 115 mm deep tank.
  SweepRequire(amplitude_mm, 0, std::min(bottom_depth_mm - 5.0, 110.0 - bottom_depth_mm),
               "amplitude_mm (with bottom_depth_mm)", true);
  const Eigen::Matrix3d r = tracker_from_world.linear();
  if (!tracker_from_world.matrix().allFinite() ||
      (r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-6 || r.determinant() < 0)
    throw std::invalid_argument("WaterTankSweepOptions: tracker_from_world is not rigid");
}

double WaterTankProbeHeightMm(const WaterTankSweepOptions& o, double t_s) {
  const double w = 2.0 * std::numbers::pi / o.period_s;
  return o.amplitude_mm * (0.7 * std::sin(w * t_s) + 0.3 * std::sin(w * t_s / 0.43 + 1.0));
}

WaterTankSweep MakeWaterTankSweep(const WaterTankSweepOptions& o) {
  o.Validate();
  SimulatedScannerOptions so;
  so.catheter = false;
  so.annulus = false;
  so.tank = true;
  so.probe.azimuth_rad = 24.0 * std::numbers::pi / 180.0;
  so.probe.elevation_rad = 2.0 * std::numbers::pi / 180.0;
  so.probe.range_mm = o.range_mm;
  so.probe.n_azimuth = o.width_px;
  so.probe.n_elevation = 3;
  so.probe.n_samples = 2 * o.depth_px;
  so.probe.volume_dims = Eigen::Vector3i(o.width_px, 3, o.depth_px);
  const double bottom_z = so.tank_max_mm.z();

  WaterTankSweep sweep;
  PlusSequence& video = sweep.video;
  video.header_fields = {{"UltrasoundImageOrientation", "MF"},
                         {"UltrasoundImageType", "BRIGHTNESS"}};
  video.frame_dims = {o.width_px, o.depth_px, 1};
  video.volume_frames = false;
  const auto frames = static_cast<std::size_t>(std::floor(o.duration_s * o.video_rate_hz)) + 1;
  for (std::size_t i = 0; i < frames; ++i) {
    const double t_rel = static_cast<double>(i) / o.video_rate_hz;
    so.probe_to_world = Eigen::Isometry3d(Eigen::Translation3d(
        0.0, 0.0, bottom_z - o.bottom_depth_mm - WaterTankProbeHeightMm(o, t_rel)));
    so.seed = o.seed * 1000003ULL + i;
    SimulatedScanner scanner(so);
    const SourceFrame frame = scanner.Render(o.start_s + t_rel);
    const Volume& v = frame.volume;
    if (i == 0) {
      video.spacing_mm = Eigen::Vector3d(v.spacing_mm().x(), v.spacing_mm().z(), 1.0);
      video.origin_mm = Eigen::Vector3d(v.origin_mm().x(), v.origin_mm().z(), 0.0);
    }
    const int mid = v.dims().y() / 2;
    for (int z = 0; z < v.dims().z(); ++z)
      for (int x = 0; x < v.dims().x(); ++x) video.pixels.push_back(v.at(x, mid, z));
    SequenceFrame f;
    f.fields["FrameNumber"] = std::to_string(i);
    f.fields["Timestamp"] = SweepTimeText(o.start_s + t_rel);
    f.fields["ImageStatus"] = "OK";
    video.frames.push_back(std::move(f));
  }

  PlusSequence& tracker = sweep.tracker;
  tracker.frame_dims = {0, 0, 0};
  tracker.element_type = "MET_OTHER";
  tracker.volume_frames = false;
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  Eigen::Isometry3d reference = Eigen::Isometry3d::Identity();
  reference.translation() = Eigen::Vector3d(40.0, 60.0, -10.0);
  const auto samples = static_cast<std::size_t>(std::floor(o.duration_s * o.tracker_rate_hz)) + 1;
  for (std::size_t k = 0; k < samples; ++k) {
    // The pose at true time t_rel, stamped tracker_lag_s late.
    const double t_rel = static_cast<double>(k) / o.tracker_rate_hz;
    Eigen::Isometry3d probe_to_world = Eigen::Isometry3d(Eigen::Translation3d(
        0.0, 0.0, bottom_z - o.bottom_depth_mm - WaterTankProbeHeightMm(o, t_rel)));
    Eigen::Isometry3d probe_to_tracker = o.tracker_from_world * probe_to_world;
    probe_to_tracker.translation() +=
        o.tracker_noise_mm * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    SequenceFrame f;
    f.fields["FrameNumber"] = std::to_string(k);
    f.fields["Timestamp"] = SweepTimeText(o.start_s + t_rel + o.tracker_lag_s);
    f.fields["ProbeToTrackerTransform"] = SweepMatrixText(probe_to_tracker.matrix());
    f.fields["ProbeToTrackerTransformStatus"] = "OK";
    f.fields["ReferenceToTrackerTransform"] = SweepMatrixText(reference.matrix());
    f.fields["ReferenceToTrackerTransformStatus"] = "OK";
    f.fields["ImageStatus"] = "INVALID";
    tracker.frames.push_back(std::move(f));
  }
  return sweep;
}

}  // namespace echoservo::imaging::sim
