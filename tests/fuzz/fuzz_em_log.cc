// Fuzz target: the EM-tracker log importer (imaging/io/em_log_import.h, formats/em_log.h): NDI
// Aurora CSV exports, the simulated tracker's em.csv and PLUS tracked sequences, as
// `echoservo report --em LOG` reads them.
//
// Input: byte 0 picks the file (bits 0-1: .csv with format auto-detected, Aurora, sim, or
// .igs.mha) and byte 1 the sensor option ("", "1", "b", "StylusToTracker"); the rest is
// the file. An accepted log must have finite, strictly increasing sample times and finite valid
// positions. Only
// std::invalid_argument may escape.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>

#include "imaging/io/em_log_import.h"
#include "tests/fuzz/fuzz_util.h"

namespace formats = echoservo::formats;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  formats::EmImportOptions options;
  const char* ext = ".csv";
  switch (data[0] & 3) {
    case 0:
      options.format = formats::EmLogFormat::kAuto;
      break;
    case 1:
      options.format = formats::EmLogFormat::kAurora;
      break;
    case 2:
      options.format = formats::EmLogFormat::kSim;
      break;
    default:
      ext = ".igs.mha";
      break;
  }
  if (data[0] & 4)
    options.units = (data[0] & 8) ? formats::LengthUnit::kInch : formats::LengthUnit::kMillimetre;
  static const char* const kSensors[] = {"", "1", "b", "StylusToTracker"};
  options.sensor = kSensors[data[1] & 3];
  const auto& path = echoservo::fuzz::Scratch().Write(ext, {data + 2, size - 2});
  try {
    const formats::EmLog log = echoservo::imaging::ReadEmLog(path, options);
    for (std::size_t i = 0; i < log.samples.size(); ++i) {
      if (!std::isfinite(log.samples[i].t_s)) __builtin_trap();
      if (i > 0 && !(log.samples[i].t_s > log.samples[i - 1].t_s)) __builtin_trap();
      if (log.samples[i].valid && !log.samples[i].position_mm.allFinite()) __builtin_trap();
    }
    (void)log.MedianPeriodS();
    (void)log.dropouts();
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
