// The planar reflector of a temporal calibration (a water-tank bottom) found in one 2D
// ultrasound frame, PLUS's way (vtkPlusLineSegmentationAlgo, PlusLib 2.8/2.9).
//
// Frame: the image's pixel grid, x lateral (columns), y depth (rows, away from the
// transducer: PLUS's MF orientation); units pixels. Stages, with PLUS's constants: 40
// vertical scanlines over the clip rectangle (x = x0 + trunc(i · (w − 1) / 39)); on each, the
// run of pixels above half the scanline's maximum with the largest intensity sum and its
// intensity centre of gravity (sub-pixel depth); a consensus line through those points (all
// pairs, inliers closer than 0.5 px orthogonally; PLUS samples pairs at random) refitted by
// orthogonal least squares on its inliers; the frame's value is |y| of that line at
// x = x0 + w / 2. Details: docs/calibration.md#video-signal
// Errors: std::invalid_argument for a frame whose size does not match, options out of range,
// or a clip rectangle whose origin lies outside the frame; a frame without a line is not an
// error (nullopt: the caller counts it).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace echoservo::tracking {

// PLUS's ClipRectangleOrigin / ClipRectangleSize (pixels). A width or height ≤ 0: the whole
// frame. A rectangle reaching past the frame is cut at its edge, as PLUS does.
struct ClipRectangle {
  int x = 0, y = 0;
  int width = 0, height = 0;
};

// The pixels searched: `clip` fitted into a width × height frame (PLUS's LimitToClipRegion).
// Throws naming the origin when it lies outside the frame (PLUS warns and uses 0 0).
struct PixelRegion {
  int x = 0, y = 0, width = 0, height = 0;
};
PixelRegion FitClipToFrame(const ClipRectangle& clip, int width, int height);

struct ReflectorLineOptions {
  ClipRectangle clip;             // whole frame: PLUS's TemporalCalibration tool default
  int scanlines = 40;             // NUMBER_OF_SCANLINES, ≥ 2
  double peak_fraction = 0.5;     // INTESNITY_THRESHOLD_PERCENTAGE_OF_PEAK, (0, 1]
  double inlier_px = 0.5;         // RANSAC maximalDistanceFromPlane (orthogonal), > 0
  double min_direction_x = 0.01;  // MIN_X_SLOPE_COMPONENT_FOR_DETECTED_LINE, [0, 1)
  // Not PLUS's: remove the sweep's static background (the per-pixel median of up to 31
  // frames) before searching; used by ReflectorSignal (tracking/temporal_calibration.h).
  bool subtract_static_background = false;
};

// One scanline's brightest run (PLUS's FindLargestPeak): the pixels in [start, end) all above
// fraction · max(profile), the run with the largest intensity sum (the first on ties). A run
// still open at the profile's end is not a peak; a pixel equal to the threshold neither opens
// nor closes a run.
struct ScanlinePeak {
  int start = 0, end = 0;  // [start, end), indices into the profile
  int max = 0;             // its brightest pixel
  long long area = 0;      // its intensity sum
};
std::optional<ScanlinePeak> LargestPeak(std::span<const int> profile, double fraction);

// PLUS's ComputeCenterOfGravity: Σ i · I(i) / Σ I(i) from `start` while I(i) > fraction ·
// max(profile). nullopt when that sum is 0 or the run reaches the profile's end.
std::optional<double> PeakCentreOfGravity(std::span<const int> profile, int start, double fraction);

// The scanlines' columns: x + trunc(i · (width − 1) / (count − 1)), i = 0 … count − 1.
std::vector<int> ScanlineColumns(const PixelRegion& region, int count);

// A line through pixel points: the consensus set of the pair whose line has the most points
// closer than `inlier_px` (orthogonal, strictly; the first pair in (i, j) order on ties),
// refitted by orthogonal least squares (PLUS's PlaneParametersEstimator). `direction` has
// the sign PLUS's eigen-solver gives it (EISPACK via vnl): its x component is positive
// unless the points spread more along y than x and the line falls to the right (slope < −1).
struct ConsensusLine {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();       // the inliers' mean, pixels
  Eigen::Vector2d direction = Eigen::Vector2d::UnitX();  // unit
  int inliers = 0;
  double rms_px = 0.0;  // inliers' orthogonal distance RMS
};
// nullopt for fewer than 2 points or no two distinct points.
std::optional<ConsensusLine> FitConsensusLine(std::span<const Eigen::Vector2d> points,
                                              double inlier_px);

struct ReflectorLine {
  double depth_px = 0.0;  // |y| of the line at x = region.x + region.width / 2 (PLUS's metric)
  double slope = 0.0;     // dy/dx
  int scanlines = 0;      // scanlines with a peak
  int inliers = 0;        // of them on the line
  double rms_px = 0.0;    // inliers' orthogonal RMS
};

// `pixels`: width × height uint8, x fastest (row after row). nullopt when fewer than 2
// scanlines have a peak, or the line's direction has an x component below min_direction_x
// (near vertical, or PLUS's sign rule above).
std::optional<ReflectorLine> FindReflectorLine(std::span<const std::uint8_t> pixels, int width,
                                               int height,
                                               const ReflectorLineOptions& options = {});

}  // namespace echoservo::tracking
