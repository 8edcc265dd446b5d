// EM-tracker logs in any format `echoservo report` reads: PLUS tracked sequences here (they
// need this module's sequence reader), NDI Aurora CSV exports and the simulated tracker's
// em.csv through formats/em_log.h, whose EmLog they all produce (positions in mm in the
// tracker's frame, times in s on the tracker's clock).
//
// PLUS: one sample per frame at its Timestamp (else UnfilteredTimestamp), the translation of
// the chosen tool's `<Tool>Transform` (e.g. StylusToTracker); a status other than OK, or no
// transform, is a drop-out counted under that status ("absent").
// Errors: std::invalid_argument naming the frame: no timestamp, a transform that is not 16
// finite numbers on an OK frame, times that do not strictly increase; listing the tools when
// none is named and several have data.
// Details: docs/report.md#em-tracker-logs
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "formats/em_log.h"
#include "imaging/io/plus_sequence.h"

namespace echoservo::imaging {

// Names of the tools with a `<Name>Transform` field in any frame (without the suffix),
// sorted: e.g. ProbeToTracker, ReferenceToTracker, StylusToTracker.
std::vector<std::string> PlusTrackerTools(const PlusSequence& sequence);

// The tool options.sensor names (with or without the Transform suffix), or the only tool
// when it is empty; throws std::invalid_argument listing the tools (with their OK frame
// counts) otherwise.
formats::EmLog PlusSequenceToEmLog(const PlusSequence& sequence,
                                   const std::filesystem::path& source,
                                   const formats::EmImportOptions& options);

formats::EmLog ReadPlusEmLog(const std::filesystem::path& path,
                             const formats::EmImportOptions& options);

// Any format: options.format, or formats::DetectEmLogFormat when it is kAuto.
formats::EmLog ReadEmLog(const std::filesystem::path& path,
                         const formats::EmImportOptions& options);

}  // namespace echoservo::imaging
