// Electromagnetic-tracker logs: the timed positions of one tracked sensor (the catheter
// tip's EM sensor), with its drop-outs, as `echoservo report` compares them with the image.
//
// Units and frames: positions in mm in the EM tracker's own frame (field generator), times
// in s on its own clock; report/em_alignment.h estimates the EM→image transform and the
// clock offset. Files in inches must be declared (EmImportOptions::units); nothing is
// guessed from the values. Formats read here: the NDI Aurora CSV export and the simulated
// tracker's em.csv (PLUS sequences: imaging/io/em_log_import.h).
// Errors: std::invalid_argument naming the file, line and field: times that do not strictly
// increase, NaN or infinite numbers, malformed rows, units contradicting the file's own.
// Details: docs/report.md#em-tracker-logs
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace echoservo::formats {

enum class EmLogFormat { kAuto, kPlus, kAurora, kSim };
// "auto", "plus", "aurora", "sim"; throws std::invalid_argument naming the text.
EmLogFormat ParseEmLogFormat(const std::string& text);
const char* EmLogFormatName(EmLogFormat format);

enum class LengthUnit { kMillimetre, kInch };
// "mm", "in"; throws std::invalid_argument naming the text.
LengthUnit ParseLengthUnit(const std::string& text);
const char* LengthUnitName(LengthUnit unit);
double MillimetresPerUnit(LengthUnit unit);

struct EmSample {
  double t_s = 0.0;                                       // EM tracker clock
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();  // EM frame; zero when !valid
  bool valid = false;
};

struct EmLog {
  std::filesystem::path source;
  EmLogFormat format = EmLogFormat::kSim;
  std::string sensor;                // the sensor or tool the samples are of
  std::vector<std::string> sensors;  // every sensor or tool in the file
  LengthUnit file_units = LengthUnit::kMillimetre;
  std::vector<EmSample> samples;  // strictly increasing t_s
  // Drop-outs by reason ("all zeros", "MISSING", "INVALID", "sample number gap", …); a
  // gap in the Aurora sample numbers counts its missing samples, which have no entry in
  // `samples`.
  std::map<std::string, std::size_t> dropouts_by_reason;
  std::vector<std::string> notes;  // non-fatal remarks (a truncated last row skipped, …)

  std::size_t valid_samples() const;
  std::size_t dropouts() const;  // sum of dropouts_by_reason
  double MedianPeriodS() const;  // of all samples; NaN with fewer than 2
};

struct EmImportOptions {
  EmLogFormat format = EmLogFormat::kAuto;
  // Declared units. nullopt: the file's own (the sim header's column suffix), else mm. A
  // declaration that contradicts the file's own units is an error.
  std::optional<LengthUnit> units;
  // Aurora: the sensor as a 1-based index or its column letter (a, b, …); PLUS: the tool's
  // transform name (e.g. StylusToTracker). Empty: the only sensor or tool with data; an
  // error listing them when there are several.
  std::string sensor;
};

// Appends samples in time order for the importers: scales positions to mm and throws
// std::invalid_argument naming `where` (e.g. "em.csv: line 12") when a time is not finite
// or not after the previous sample's.
class EmLogAppender {
 public:
  EmLogAppender(EmLog& log, LengthUnit units);
  void AddValid(double t_s, const Eigen::Vector3d& position, const std::string& where);
  void AddDropout(double t_s, const std::string& reason, const std::string& where);
  // Drop-outs without a sample (e.g. missing sample numbers).
  void CountMissing(const std::string& reason, std::size_t count);

 private:
  void CheckTime(double t_s, const std::string& where);
  EmLog& log_;
  double scale_;
  std::string previous_where_;
};

// By extension (.mha, .nrrd: PLUS) and the first lines (an Aurora preamble or `Sample:`
// header: aurora; a `t_s` first column: sim). Throws std::invalid_argument when none fits.
EmLogFormat DetectEmLogFormat(const std::filesystem::path& path);

// The units an import uses: the declared ones, or `file_units` (when the file states them),
// else mm. Throws std::invalid_argument naming the file when they contradict.
LengthUnit ResolveUnits(const std::filesystem::path& path, const EmImportOptions& options,
                        std::optional<LengthUnit> file_units);

EmLog ReadAuroraEmLog(const std::filesystem::path& path, const EmImportOptions& options);
EmLog ReadSimEmLog(const std::filesystem::path& path, const EmImportOptions& options);

// The sim format's header and one row (no newline), as formats/run_record.h writes em.csv.
std::string SimEmLogHeader();
std::string SimEmLogRow(const EmSample& sample);

}  // namespace echoservo::formats
