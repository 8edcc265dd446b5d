// The typed metadata of a RUN directory (formats/run_record.h): what run.json says about the
// run besides its heart rate and standoff — which command wrote it, the clock its times are
// on, the EM tracker's calibration to the image, the pipeline settings it ran with. Written
// and read only by formats/run_record.cc; nothing else formats or parses run.json.
//
// Frames and units: EmToImage maps EM-tracker mm to image mm (rigid); times in s.
// File form (docs/report.md#the-run-directory): "source", "time_base" ("pipeline", "unix",
// "recording"), "em_to_image" (a string of 12 or 16 numbers, row-major), "seed",
// "duration_s", "replay_of", "pipeline_to_unix_s", "settings" ({"name": number}).
// Errors: std::invalid_argument naming the file and the key (a wrong type, a value out of
// range, a transform that is not rigid). A RUN written before these keys existed is read as
// before, with a warning (RunInfo::warnings).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace echoservo::formats {

// The clock of a RUN's times.
enum class RunTimeBase {
  kUnstated,   // run.json does not say (a RUN written before typed metadata)
  kPipeline,   // s since the run's start (the demo's and `track --sim`'s pipeline clock)
  kUnix,       // s since the Unix epoch (a scanner stamping wall-clock time, or arrival)
  kRecording,  // the replayed recording's own timestamps
};
std::string_view ToString(RunTimeBase base);  // "pipeline", ... ("" for kUnstated)

struct RunMetadata {
  std::string source;  // the command that wrote the RUN, e.g. "echoservo demo"
  RunTimeBase time_base = RunTimeBase::kUnstated;
  std::optional<Eigen::Isometry3d> em_to_image;  // EmToImage, measured before the run
  std::optional<std::uint64_t> seed;             // a simulation's seed
  std::optional<double> duration_s;              // the run's requested length, > 0
  std::string replay_of;                         // a replay: the recording's path
  // Clock facts: Unix time = pipeline time + pipeline_to_unix_s (measured once at the start).
  std::optional<double> pipeline_to_unix_s;
  // Every pipeline parameter's value by name (live/pipeline_parameters.h), sorted by name.
  std::vector<std::pair<std::string, double>> settings;
};

// A rigid transform from 12 or 16 numbers, row-major (separated by commas and/or spaces).
// Throws std::invalid_argument "`where`: ..." for a wrong count, a non-number, or a matrix
// that is not a rotation and a translation (tolerance 1e-3 on RᵀR − I).
Eigen::Isometry3d ParseRigidTransform(std::string_view text, std::string_view where);
// The 3 × 4 rows, comma-separated, "%.9g" (what ParseRigidTransform reads back).
std::string FormatRigidTransform(const Eigen::Isometry3d& t);

}  // namespace echoservo::formats
