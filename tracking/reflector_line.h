// The planar reflector of a temporal calibration (a water-tank bottom) found in one 2D
// ultrasound frame: a bright straight line across the image, located with sub-pixel
// precision.
//
// Frame: the image's pixel grid, x lateral (columns, index 0 … width − 1), y depth (rows,
// growing away from the transducer: PLUS's MF orientation). Units: pixels (multiply by the
// frame's spacing for mm). Method: per column, the brightest run above a threshold and its
// intensity centre of gravity (sub-pixel depth); then a RANSAC line through those points
// (pairs of columns, inliers within inlier_px) refined by least squares on the inliers. The
// reflector's position is the line's depth at the central column.
// Errors: std::invalid_argument for a frame whose size does not match width × height or
// options out of range; a frame without a line is not an error (nullopt: the caller counts
// it).
#pragma once

#include <cstdint>
#include <optional>
#include <span>

namespace echoservo::tracking {

struct ReflectorLineOptions {
  // A column's peak counts when it reaches this share of the frame's brightest pixel …
  double peak_fraction = 0.5;
  // … and at least this intensity (0-255), so that speckle in an empty frame is no line.
  double min_peak = 40.0;
  double inlier_px = 2.0;      // RANSAC inlier distance (pixels, along the depth axis)
  double min_inliers = 0.3;    // share of the columns that must lie on the line
  int ransac_iterations = 64;  // pairs tried (deterministic sequence)
  // Ignore rows nearer than this to the transducer (its ring-down), pixels.
  int skip_rows = 0;
  // Used by ReflectorSignal (tracking/temporal_calibration.h), not by FindReflectorLine:
  // remove the sweep's static background from every frame first.
  bool subtract_static_background = true;
};

struct ReflectorLine {
  double depth_px = 0.0;  // the line's depth (y) at the central column x = (width − 1) / 2
  double slope = 0.0;     // d(depth)/d(x), pixels per pixel
  int columns = 0;        // columns with a peak
  int inliers = 0;        // of them on the line
  double rms_px = 0.0;    // inliers' depth residual RMS
};

// `pixels`: width × height uint8, x fastest (row after row). nullopt when fewer than
// max(3, min_inliers · width) columns support a line.
std::optional<ReflectorLine> FindReflectorLine(std::span<const std::uint8_t> pixels, int width,
                                               int height,
                                               const ReflectorLineOptions& options = {});

}  // namespace echoservo::tracking
