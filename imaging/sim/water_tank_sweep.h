// A simulated temporal-calibration recording: a probe moved up and down over a water tank's
// flat bottom, imaged by the simulated scanner (imaging/sim/simulated_scanner.h, ray traced)
// and tracked by a simulated tracker whose clock lags the scanner's by a known amount.
//
// Frames: world = the tank's (probe looking down +z at the tank bottom, z = tank_max_mm.z);
// the probe moves along world z; the tracker's frame is world rotated and shifted
// (tracker_from_world), so the motion is along no tracker axis. Video: 2D frames (the middle
// elevation slice of a thin volume: x lateral, y depth; PLUS's MF orientation), a PLUS video
// sequence at video_rate_hz, stamped with their acquisition times. Tracker: ProbeToTracker
// (+ a still ReferenceToTracker) at tracker_rate_hz, each pose stamped tracker_lag_s late
// (PLUS's sign: the tracker stream lags the video by tracker_lag_s;
// docs/calibration.md#sign-convention). Units: mm, s.
// Errors: std::invalid_argument naming the option out of range.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>

#include "imaging/io/plus_sequence.h"

namespace echoservo::imaging::sim {

struct WaterTankSweepOptions {
  double duration_s = 8.0;        // (0, 600]
  double video_rate_hz = 25.0;    // (0, 200]
  double tracker_rate_hz = 40.0;  // (0, 1000]
  double tracker_lag_s = 0.0;     // |·| ≤ 5
  double start_s = 1000.0;        // first video timestamp (the scanner's clock)
  // Probe height above its mean: amplitude · (0.7 sin(2π t / period) + 0.3 sin(2π t /
  // (0.43 period) + 1)): a hand-like, non-symmetric up-and-down motion (mm, s).
  double amplitude_mm = 12.0;      // (0, 40]
  double period_s = 1.5;           // [0.2, 60]
  double bottom_depth_mm = 60.0;   // mean probe-to-bottom distance (true mm), [20, 100]
  double tracker_noise_mm = 0.05;  // Gaussian SD per axis, [0, 5]
  std::uint64_t seed = 1;
  // The scanner's 2D frame: lateral pixels, depth pixels, field of view.
  int width_px = 96;        // [16, 1024]
  int depth_px = 240;       // [16, 2048]
  double range_mm = 120.0;  // displayed depth of the frame, (bottom + amplitude, 300]
  Eigen::Isometry3d tracker_from_world = DefaultTrackerFromWorld();

  static Eigen::Isometry3d DefaultTrackerFromWorld();
  // Throws std::invalid_argument naming the field.
  void Validate() const;
};

struct WaterTankSweep {
  PlusSequence video;    // 2D frames, Timestamp = acquisition time (scanner clock)
  PlusSequence tracker;  // tracker-only (DimSize 0 0 N), Timestamp on the tracker's clock
};

// Renders every frame (one simulated-scanner volume per frame).
WaterTankSweep MakeWaterTankSweep(const WaterTankSweepOptions& options);

// The probe's height above its mean position along world z at true time t (mm): positive
// moves the probe away from the bottom (the bottom's echo deepens).
double WaterTankProbeHeightMm(const WaterTankSweepOptions& options, double t_s);

}  // namespace echoservo::imaging::sim
