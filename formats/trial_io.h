// The trial format: one bench recording of the catheter (docs/trial_format.md).
//
// A trial is a CSV sampled at 1 kHz with the header `t,base_cmd,base,tip,force`
// (s, mm, mm, mm, N; extra columns allowed and kept) and a sibling JSON with the
// catheter geometry: `sheath_id_mm`, `guidewire_od_mm`, `bends` (list of
// {"angle_deg", "radius_mm"}) and `tip_load_n`. A dataset is a folder of such pairs
// (name.csv + name.json). Readers validate everything: a bad file produces
// std::invalid_argument (TrialFormatError) naming the file, the line or key, and why.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "formats/catheter_config.h"

namespace echoservo::formats {

class TrialFormatError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

struct Trial {
  std::string name;  // file stem
  CatheterConfig config;
  std::vector<double> t_s;
  std::vector<double> base_cmd_mm;
  std::vector<double> base_mm;
  std::vector<double> tip_mm;
  std::vector<double> force_n;
  // Extra CSV columns, kept in file order.
  std::vector<std::string> extra_names;
  std::vector<std::vector<double>> extra_columns;
  // Free-form metadata from the JSON's optional "meta" object, serialised as JSON text.
  std::string meta_json = "{}";
  // Non-fatal remarks from the reader (e.g. unknown JSON keys it ignored).
  std::vector<std::string> warnings;

  std::size_t size() const { return t_s.size(); }
};

// Reads `csv_path` and its sibling `.json`. Throws TrialFormatError.
Trial ReadTrial(const std::filesystem::path& csv_path);
// Reads every `*.csv` with a sibling `.json` in `dir` (sorted by name). Throws
// TrialFormatError if the folder is missing, empty, or any trial is invalid.
std::vector<Trial> ReadDataset(const std::filesystem::path& dir);
// Reads a catheter configuration file: a JSON object with exactly the geometry keys of
// the trial JSON (sheath_id_mm, guidewire_od_mm, bends, tip_load_n). Unlike a trial's
// JSON, which may come from other tools, unknown keys are errors. Throws TrialFormatError.
CatheterConfig ReadCatheterConfig(const std::filesystem::path& json_path);
// Writes `<dir>/<trial.name>.csv` and `.json` (creating `dir`). Throws on I/O errors
// or an invalid trial (mismatched column lengths, non-finite values, bad geometry).
void WriteTrial(const std::filesystem::path& dir, const Trial& trial);

}  // namespace echoservo::formats
