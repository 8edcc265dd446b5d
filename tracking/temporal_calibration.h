// Temporal calibration, PLUS's way (vtkPlusTemporalCalibrationAlgo, PlusLib 2.8/2.9): the lag
// between a tracked probe's pose stream and its ultrasound image stream, from a sweep over a
// planar reflector (a water-tank bottom) with the probe moved up and down.
//
// Fixed signal: the reflector's depth per video frame (tracking/reflector_line.h; pixels).
// Moving signal: the probe's position (the translation of e.g. ProbeToTracker, or
// ProbeToReference composed from two tools, mm) projected on its principal motion direction.
// PLUS's stages and constants: the two files' common time range; the tracker cropped to it
// less max_lag at each end (and read at its end values beyond); at each trial lag L the
// tracker interpolated at t + L, both signals normalised (zero mean, unit SD; the video over
// the frames whose t + L stays in the video's span) and scored by their sum of squared
// differences over all frames; a coarse scan (one video frame period) then a fine one
// (resolution_s, ±3 periods) with no interpolation; both polarities, the smaller |lag| kept.
// Echoservo adds a confidence (Pearson r over the frames every trial lag compares, the
// peak's widths, the lag's SD) and refusals: docs/calibration.md#confidence-and-refusals.
//
// Sign (PLUS's GetMovingLagSec): tracker_lag_s > 0 means the tracker's timestamps are late by
// that much; the tracker sample stamped t + tracker_lag_s was taken when the frame stamped t
// was. Subtract it from tracker timestamps to put them on the video's clock.
// Units: s, mm, pixels. Errors: std::invalid_argument naming the file (the `source` given) and
// why: no tool or an unknown one (listing the tools), no OK transform, timestamps that
// decrease, frames of different sizes, too little motion (PLUS's 8 mm / 30 px), too little
// overlap, PLUS's SSD threshold, and echoservo's refusals (poor agreement, two peaks of
// similar height naming both lags, both polarities fitting, too flat a peak, a lag on the
// edge of the search window).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "imaging/io/plus_sequence.h"
#include "tracking/reflector_line.h"

namespace echoservo::tracking {

// Timed scalar samples, times non-decreasing (s).
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
  TimedSignal depth_px;  // the reflector's depth, per frame with a line (PLUS's fixed signal)
  // The file's first and last frame, whatever their status: PLUS's common range uses them.
  double first_frame_t_s = 0.0;
  double last_frame_t_s = 0.0;
  double spacing_mm = 1.0;     // depth pixel pitch, when spacing_known
  bool spacing_known = false;  // false: the file gives none (MetaIO's ElementSpacing 1 1)
  std::size_t frames = 0;      // in the file
  std::size_t invalid = 0;     // ImageStatus other than OK (skipped, as PLUS does)
  std::size_t no_line = 0;     // no reflector line found
  std::size_t duplicates = 0;  // a timestamp equal to the previous frame's (kept, as PLUS does)
  int width = 0, height = 0;   // frame size, pixels
  PixelRegion region;          // the pixels searched (the clip rectangle fitted to the frame)
  bool background_subtracted = false;  // ReflectorLineOptions::subtract_static_background
};

// The reflector's depth in each frame (FindReflectorLine). Throws (naming `source` and the
// frame) for frames of different sizes, times that decrease, or fewer than 2 frames.
VideoSignal ReflectorSignal(std::span<const VideoFrame> frames, const std::string& source,
                            const ReflectorLineOptions& line = {});
// The same for a PLUS video sequence: 2D frames (DimSize X Y N: y is depth), or thin 3D
// frames, whose middle y slice (an X × Z image, z depth) is used. MET_UCHAR only; frames
// with ImageStatus other than OK are skipped; a per-frame FrameSize field that differs from
// the header's DimSize is a frame of a different size (an error). The depth spacing is known
// unless the header's lateral and depth spacings are both exactly 1 (MetaIO's default, which
// PLUS writes for raw frame buffers).
VideoSignal ReflectorSignal(const imaging::PlusSequence& video, const std::string& source,
                            const ReflectorLineOptions& line = {});

// The probe's positions over its OK frames.
struct TrackerPoses {
  std::string tool;                          // e.g. ProbeToTracker; ProbeToReference when composed
  std::vector<double> t_s;                   // strictly increasing
  std::vector<Eigen::Vector3d> position_mm;  // the transform's translation
  double first_frame_t_s = 0.0;              // the file's first and last frame, any status
  double last_frame_t_s = 0.0;
  std::size_t frames = 0;      // in the file
  std::size_t duplicates = 0;  // same timestamp as the previous OK frame: the later pose kept
  std::map<std::string, std::size_t> not_ok;  // frames without an OK transform, by status
};

// `tool` with or without the Transform suffix; empty: ProbeToTracker when present, else the
// only tool. A name the file lacks, "AToB", is composed as inverse(BToC) · AToC when the file
// has both for one C (PLUS's transform repository; e.g. ProbeToReference from ProbeToTracker
// and ReferenceToTracker), OK only when both are. Throws naming `source`: tool absent
// (listing the tools), no OK frame (listing the statuses), a frame without timestamp,
// decreasing times.
TrackerPoses ReadProbePoses(const imaging::PlusSequence& tracker, const std::string& tool,
                            const std::string& source);

// PLUS's vtkPlusPrincipalMotionDetectionAlgo over the poses with t in [from_s, to_s].
struct PrincipalMotion {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();      // unit; largest component positive
  Eigen::Vector3d spread_mm = Eigen::Vector3d::Zero();  // SD along the principal axes
  TimedSignal position_mm;                              // position · axis (not centred, as PLUS)
};
// Throws std::invalid_argument naming `source` when fewer than 2 poses lie in the range.
PrincipalMotion ProjectOnPrincipalMotion(const TrackerPoses& poses, double from_s, double to_s,
                                         const std::string& source);

struct LagOptions {
  double max_lag_s = 0.5;           // PLUS's DEFAULT_MAX_MOVING_LAG_SEC (its --help says 2)
  double resolution_s = 0.001;      // fine step: DEFAULT_SAMPLING_RESOLUTION_SEC, ≥ 1e-4
  double min_tracker_p2p_mm = 8.0;  // MINIMUM_TRACKER_SIGNAL_PEAK_TO_PEAK_MM
  double min_video_p2p_px = 30.0;   // MINIMUM_VIDEO_SIGNAL_PEAK_TO_PEAK_PIXEL
  double max_plus_ssd = 502.0;      // PLUS fails a best SSD ≥ this ("-2 ^ 500" is XOR: −502)
  // Echoservo's refusals.
  std::size_t min_samples = 20;       // frames every trial lag compares
  double min_peak_r = 0.9;            // Pearson r at the lag
  double max_lag_sd_s = 0.005;        // the lag's SD
  double similar_misfit_ratio = 2.0;  // another peak whose 1 − r is within this factor
};

struct LagCurve {
  std::vector<double> lag_s;
  std::vector<double> value;
};

struct LagConfidence {
  std::size_t samples = 0;  // frames whose t ± max_lag lies in the tracker's cropped span
  double peak_r = 0.0;      // Pearson r of those frames and the tracker at the peak
  double peak_lag_s = 0.0;  // r's maximum near tracker_lag_s (a parabola over ±10 ms)
  double lag_sd_s = 0.0;  // sqrt((1 − r²) / (r · n · κ)), κ = −d²r/dL²: white residuals
  double misfit_width_s = 0.0;  // the lags whose 1 − r ≤ 2 (1 − peak_r)
  double fwhm_s = 0.0;          // the peak's width at half its height above the curve's floor
  double second_lag_s = std::numeric_limits<double>::quiet_NaN();  // best other local maximum
  double second_r = std::numeric_limits<double>::quiet_NaN();
  double other_polarity_lag_s = 0.0;  // the negated tracker's best lag and r (= −min r)
  double other_polarity_r = 0.0;
  LagCurve curve;  // r at every resolution_s over ±max_lag, chosen polarity
};

struct LagResult {
  double tracker_lag_s = 0.0;                     // PLUS's figure (on its fine grid), PLUS's sign
  bool inverted = false;                          // the tracker signal was negated
  double other_lag_s = 0.0;                       // the other polarity's PLUS figure
  double common_from_s = 0.0, common_to_s = 0.0;  // the files' common time range
  double moving_from_s = 0.0, moving_to_s = 0.0;  // tracker samples used
  std::size_t video_samples_used = 0;             // frames with a line in the common range
  std::size_t tracker_samples_used = 0;           // poses in the moving range
  double video_p2p_px = 0.0;
  double tracker_p2p_mm = 0.0;
  double coarse_step_s = 0.0;           // the video frame period (first to last frame used)
  double coarse_lag_s = 0.0;            // the coarse scan's best, chosen polarity
  double plus_ssd = 0.0;                // the best sum of squared differences (normalised signals)
  double plus_calibration_error = 0.0;  // PLUS's CalibrationError: √SSD · SD(tracker), mm
  double plus_max_calibration_error = 0.0;          // PLUS's MaxCalibrationError, mm
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // principal direction (moving range)
  LagCurve coarse, fine;                            // PLUS's metric (−SSD), chosen polarity
  LagConfidence confidence;
  double correlation = 0.0;  // confidence.peak_r
};

// Throws std::invalid_argument naming video_source / tracker_source (see above).
LagResult EstimateTrackerLag(const VideoSignal& video, const TrackerPoses& tracker,
                             const LagOptions& options, const std::string& video_source,
                             const std::string& tracker_source);

}  // namespace echoservo::tracking
