// Accuracy harness of the catheter detectors: runs the fast Radon detector (full search and
// tracking mode), the RANSAC baseline and optionally the exhaustive full-resolution Radon
// reference on the volume classes of tracking/accuracy_volumes.h, in one process, against the
// simulator's ground truth; the numbers behind `echoservo bench detect` and
// tests/tracking/detector_accuracy_test.cc.
//
// Methods ("fast", "tracking", "ransac", "exhaustive"):
//   fast       RadonDetector::Detect(volume), full search;
//   tracking   RadonDetector::Detect(next, previous): the class's second frame (catheter
//              advanced 1 mm) searched near the fast full search's axis on the first frame
//              (a plain full search when that found nothing); catheter classes only;
//   ransac     RansacLineDetector::Detect(volume);
//   exhaustive ExhaustiveRadonAxis(volume): axis only (angle and offset errors; no tip or
//              target), catheter classes only — on catheter-free volumes it still reports its
//              strongest line, so false detections mean nothing for it.
// Errors, as Measure() in tests/tracking/radon_detector_test.cc: axis angle between the
// detected and true axes (deg, sign ignored); axis offset = distance from the true tip to the
// detected axis (mm); tip = |detected − true tip| (mm); target = |detected − true target|
// (mm), over volumes whose true target is visible, +∞ when the method found no target.
// Errors are taken over the volumes the method detected; the detection rate says how many
// that was. Catheter-free classes count false detections (found = true). A detector throwing
// std::invalid_argument counts as not found (and in `errors`). Times: std::chrono::steady_clock
// around each call, ms per volume (the volume's rendering or loading excluded).
// Agreement (fast vs exhaustive): angle between their axes and the distance from the fast
// tip to the exhaustive axis, over volumes the fast detector found.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "tracking/exhaustive_radon.h"
#include "tracking/radon_detector.h"
#include "tracking/ransac_line_detector.h"

namespace echoservo::tracking {

struct DetectorAccuracyOptions {
  int volumes_per_class = 2;           // [1, 1000]; the real spine_phantom class has one volume
  std::vector<std::string> classes;    // names from VolumeClasses(); empty: all
  bool tracking = true;                // render the second frames and run tracking mode
  bool ransac = true;
  bool exhaustive = false;             // seconds per volume
  std::filesystem::path spine_volume;  // the real volume; empty: spine_phantom is skipped
  std::uint64_t seed = 1;
  RadonDetectorOptions fast;
  RansacLineDetectorOptions ransac_options;
  ExhaustiveRadonOptions exhaustive_options;
  std::function<void(const std::string&)> log;  // one line per volume, optional

  // Throws std::invalid_argument naming the field (or the unknown class).
  void Validate() const;
};

// Median and 95th percentile (nearest rank) of a sample that may hold +∞ (a miss); NaN when
// the sample is empty.
struct Quantiles {
  int count = 0;
  double median = std::numeric_limits<double>::quiet_NaN();
  double p95 = std::numeric_limits<double>::quiet_NaN();
};
Quantiles ComputeQuantiles(std::vector<double> values);

struct MethodStats {
  std::string method;
  int volumes = 0;            // volumes the method ran on
  int detected = 0;           // found = true
  int errors = 0;             // std::invalid_argument thrown
  double detection_rate = 0;  // detected / volumes (catheter classes)
  Quantiles angle_deg, offset_mm, tip_mm, target_mm;  // catheter classes
  int false_detections = 0;   // catheter-free classes: = detected
  double mean_ms = 0, median_ms = 0;
};

struct ClassStats {
  std::string name;
  std::string description;
  bool catheter = true;
  int volumes = 0;
  std::vector<MethodStats> methods;
  Quantiles agreement_angle_deg, agreement_offset_mm;  // fast vs exhaustive

  const MethodStats* Method(std::string_view method) const;  // nullptr when not run
};

struct VolumeRecord {  // one method on one volume
  std::string class_name;
  int index = 0;
  std::string label;
  std::string method;
  bool found = false;
  double angle_deg = 0, offset_mm = 0, tip_mm = 0, target_mm = 0;  // 0 when not applicable
  double confidence = 0;
  double ms = 0;
};

struct DetectorAccuracyReport {
  std::vector<ClassStats> classes;
  std::vector<MethodStats> overall;  // every class pooled: times, detections, false detections
  Quantiles agreement_angle_deg, agreement_offset_mm;
  std::vector<VolumeRecord> records;
  std::vector<std::string> skipped;  // classes or volumes left out, with the reason
};

DetectorAccuracyReport RunDetectorAccuracy(const DetectorAccuracyOptions& options);

}  // namespace echoservo::tracking
