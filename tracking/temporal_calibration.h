// Temporal calibration, PLUS's way: the lag between a tracked probe's pose stream and its
// ultrasound image stream, from a sweep over a planar reflector (a water-tank bottom) with
// the probe moved up and down.
//
// Video signal: the reflector's depth in each frame (tracking/reflector_line.h; pixels and
// mm). Tracker signal: the probe's position (translation of e.g. ProbeToTracker, mm, tracker
// frame) projected on its principal motion direction (PCA of the positions). Both are
// normalised (zero mean, unit SD over the compared samples: a Pearson correlation) and
// compared at every trial lag L: the tracker signal, linearly interpolated at t + L, against
// the video signal at t, for the video samples whose t ± max_lag lies in the tracker's span.
// A coarse scan (one video frame period) then a fine one (resolution_s, ±3 periods) and a
// parabola through the best three fine values give the lag with sub-sample resolution.
// The sign of the motion is unknown (the reflector's depth falls as the probe moves down),
// so both polarities are tried; like PLUS, the smaller |lag| is kept among the polarities
// that correlate (|r| within polarity_tolerance of the best).
//
// Sign (PLUS's, vtkPlusTemporalCalibrationAlgo: "the time by which the tracker stream lags
// the video stream", minimising Σ|Video(t) − Tracker(t + lag)|): tracker_lag_s > 0 means the
// tracker's timestamps are late by that much; the tracker sample stamped t + tracker_lag_s
// was taken when the frame stamped t was. Subtract it from tracker timestamps to put them on
// the video's clock. Details: docs/calibration.md#sign-convention
// Units: s, mm, pixels. Errors: std::invalid_argument naming the file (the `source` given)
// and why: no tool or an unknown one (listing the tools), no OK transform, timestamps that
// decrease, frames of different sizes, too little motion (PLUS's limits: 8 mm tracker,
// 30 px video peak-to-peak), too little overlap, a lag on the edge of the search window.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "imaging/io/plus_sequence.h"
#include "tracking/reflector_line.h"

namespace echoservo::tracking {

// Timed scalar samples, times strictly increasing (s).
struct TimedSignal {
  std::vector<double> t_s;
  std::vector<double> value;
  std::size_t size() const { return t_s.size(); }
};

// One 2D frame (uint8, x lateral fastest, y depth).
struct VideoFrame {
  double t_s = 0.0;
  int width = 0;
  int height = 0;
  std::span<const std::uint8_t> pixels;
};

struct VideoSignal {
  TimedSignal depth_px;        // the reflector's depth at the central column, per frame found
  double spacing_mm = 1.0;     // depth pixel pitch: depth_mm = depth_px · spacing_mm
  std::size_t frames = 0;      // in the file
  std::size_t invalid = 0;     // ImageStatus other than OK
  std::size_t no_line = 0;     // no reflector line found
  std::size_t duplicates = 0;  // a timestamp equal to the previous frame's (skipped)
  int width = 0, height = 0;   // frame size, pixels
  bool background_subtracted = false;  // the static background was removed (see below)
};

// The reflector's depth in each frame, after removing the static background (the per-pixel
// median of up to 31 frames spread over the sweep: ring-down, housing reverberations,
// overlays; with line.subtract_static_background and at least 8 frames). Throws (naming
// `source` and the frame) for frames of different sizes, times that decrease, or fewer than
// 2 frames.
VideoSignal ReflectorSignal(std::span<const VideoFrame> frames, const std::string& source,
                            const ReflectorLineOptions& line = {});
// The same for a PLUS video sequence: 2D frames (DimSize X Y N: y is depth), or thin 3D
// frames, whose middle y slice (an X × Z image, z depth) is used. MET_UCHAR only; frames
// with ImageStatus other than OK are skipped; a per-frame FrameSize field that differs from
// the header's DimSize is a frame of a different size (an error).
VideoSignal ReflectorSignal(const imaging::PlusSequence& video, const std::string& source,
                            const ReflectorLineOptions& line = {});

struct TrackerSignal {
  std::string tool;                                 // e.g. ProbeToTracker
  TimedSignal position_mm;                          // along `axis`, about the mean position
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // principal motion direction (tracker frame)
  Eigen::Vector3d spread_mm = Eigen::Vector3d::Zero();  // SD along the principal axes
  std::size_t frames = 0;                               // in the file
  std::size_t duplicates = 0;                 // same timestamp as the previous OK sample (skipped)
  std::map<std::string, std::size_t> not_ok;  // frames without an OK transform, by status
};

// The tool's translation over its OK frames, projected on its principal direction. `tool`
// with or without the Transform suffix; empty: ProbeToTracker when present, else the only
// tool. Throws naming `source`: tool absent (listing the tools), no OK frame (listing the
// statuses), a frame without timestamp, decreasing times.
TrackerSignal ProbeMotionSignal(const imaging::PlusSequence& tracker, const std::string& tool,
                                const std::string& source);

struct LagOptions {
  double max_lag_s = 2.0;            // search window ±, PLUS's default
  double resolution_s = 0.001;       // fine scan step, PLUS's default
  double min_tracker_p2p_mm = 8.0;   // PLUS: MINIMUM_TRACKER_SIGNAL_PEAK_TO_PEAK_MM
  double min_video_p2p_px = 30.0;    // PLUS: MINIMUM_VIDEO_SIGNAL_PEAK_TO_PEAK_PIXEL
  std::size_t min_samples = 20;      // video samples compared
  double polarity_tolerance = 0.05;  // |r| within this of the best: a candidate polarity
};

struct LagResult {
  double tracker_lag_s = 0.0;  // PLUS's sign (see above)
  double correlation = 0.0;    // Pearson r of the aligned signals at that lag, chosen polarity
  bool inverted = false;       // the tracker signal was negated (reflector depth vs position)
  double other_lag_s = 0.0;    // the other polarity's best lag and r
  double other_correlation = 0.0;
  std::size_t video_samples_used = 0;
  std::size_t tracker_samples_used = 0;
  double video_p2p_px = 0.0;  // over the samples used
  double tracker_p2p_mm = 0.0;
  double coarse_step_s = 0.0;
  double window_from_s = 0.0, window_to_s = 0.0;  // video times compared
  std::vector<double> scan_lag_s, scan_r;         // the coarse scan (r of the unflipped signals)
};

// `video` (reflector depth, px) and `tracker` (position, mm) on their own clocks. Throws
// std::invalid_argument naming video_source / tracker_source (see above).
LagResult EstimateTrackerLag(const TimedSignal& video, const TimedSignal& tracker,
                             const LagOptions& options, const std::string& video_source,
                             const std::string& tracker_source);

}  // namespace echoservo::tracking
