// Fuzz target: the trial reader (formats/trial_io.h, formats/csv_table.h): a trial CSV and its
// sibling JSON, as `echoservo lab` reads a dataset, and a catheter configuration file
// (ReadCatheterConfig, `sim track --catheter FILE.json`).
//
// Input: the JSON, a NUL byte, then the CSV (no NUL: the whole input is the CSV and the JSON
// is a fixed valid one). An accepted trial must have equal-length, finite columns and a
// strictly increasing time. Only std::invalid_argument (TrialFormatError, CsvFormatError)
// may escape.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "formats/trial_io.h"
#include "tests/fuzz/fuzz_util.h"

namespace formats = echoservo::formats;

namespace {

constexpr std::string_view kDefaultJson =
    R"({"sheath_id_mm": 1.2, "guidewire_od_mm": 0.9, "bends": [{"angle_deg": 90, "radius_mm": 50}], "tip_load_n": 0})";

bool AllFinite(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  const auto nul = std::find(bytes.begin(), bytes.end(), std::uint8_t{0});
  std::span<const std::uint8_t> json(reinterpret_cast<const std::uint8_t*>(kDefaultJson.data()),
                                     kDefaultJson.size());
  std::span<const std::uint8_t> csv = bytes;
  if (nul != bytes.end()) {
    json = bytes.first(static_cast<std::size_t>(nul - bytes.begin()));
    csv = bytes.subspan(json.size() + 1);
  }
  auto& scratch = echoservo::fuzz::Scratch();
  const auto& json_path = scratch.Write(".json", json);
  const auto& csv_path = scratch.Write(".csv", csv);  // same stem: the trial's sibling JSON
  try {
    (void)formats::ReadCatheterConfig(json_path);
  } catch (const std::invalid_argument&) {
  }
  try {
    const formats::Trial trial = formats::ReadTrial(csv_path);
    const std::size_t n = trial.size();
    if (trial.base_cmd_mm.size() != n || trial.base_mm.size() != n || trial.tip_mm.size() != n ||
        trial.force_n.size() != n || trial.extra_columns.size() != trial.extra_names.size())
      __builtin_trap();
    if (!AllFinite(trial.t_s) || !AllFinite(trial.base_cmd_mm) || !AllFinite(trial.base_mm) ||
        !AllFinite(trial.tip_mm) || !AllFinite(trial.force_n))
      __builtin_trap();
    for (const auto& c : trial.extra_columns)
      if (c.size() != n || !AllFinite(c)) __builtin_trap();
    for (std::size_t i = 1; i < n; ++i)
      if (!(trial.t_s[i] > trial.t_s[i - 1])) __builtin_trap();
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
