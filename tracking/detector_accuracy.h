// Accuracy harness of the catheter detectors: the fast Radon detector (full search and
// tracking), the RANSAC baseline and optionally the exhaustive reference, run in one process
// on the volume classes of tracking/accuracy_volumes.h against the simulator's ground truth;
// the numbers behind `echoservo bench detect` and tests/tracking/detector_accuracy_test.cc.
//
// Out, per class and method over the detected volumes: median and p95 of the axis angle (deg)
// and of the axis offset, tip and target errors (mm; target +∞ when not found), the detection
// rate, false detections and wall time (ms per volume). A detector throwing
// std::invalid_argument counts as not found (MethodStats::errors).
// Errors: Validate throws std::invalid_argument naming the field or the unknown class.
// Details: docs/detector.md#accuracy-harness-and-echoservo-bench-detect
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
  int volumes_per_class = 2;         // [1, 1000]; the real spine_phantom class has one volume
  std::vector<std::string> classes;  // names from VolumeClasses(); empty: all
  bool tracking = true;              // render the second frames and run tracking mode
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
  int volumes = 0;                                    // volumes the method ran on
  int detected = 0;                                   // found = true
  int errors = 0;                                     // std::invalid_argument thrown
  double detection_rate = 0;                          // detected / volumes (catheter classes)
  Quantiles angle_deg, offset_mm, tip_mm, target_mm;  // catheter classes
  // Signed tip error along the true axis (mm; < 0: short of the true tip): its median is the
  // tip's bias, its p95 the largest overshoot.
  Quantiles tip_along_mm;
  int false_detections = 0;                         // catheter-free classes: = detected
  double mean_detect_ms = 0, median_detect_ms = 0;  // wall time per volume
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
  double detect_ms = 0;     // wall time of the detection
  double tip_along_mm = 0;  // signed tip error along the true axis (< 0: short)
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
