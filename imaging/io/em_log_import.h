// EM-tracker logs in any format `echoservo report` reads: PLUS tracked sequences here (they
// need this module's sequence reader), NDI Aurora CSV exports and the simulated tracker's
// em.csv through hw/em_log.h, whose EmLog they all produce (positions in mm in the
// tracker's frame, times on the tracker's clock).
//
// PLUS (.igs.mha, .igs.nrrd, tracker-only or with images): one sample per frame, at the
// frame's Timestamp (else UnfilteredTimestamp; a frame with neither is an error), the
// position the translation of the chosen tool's `<Tool>Transform` (e.g. StylusToTracker: the
// tool's origin in the tracker frame). The tool's `<Tool>TransformStatus` decides: OK (or no
// status field with the transform present) is a sample; any other status (INVALID,
// MISSING, OUT_OF_VIEW, …, as PLUS writes them, trailing spaces trimmed) or an absent
// transform is a drop-out counted under that status ("absent"). A transform that is not 16
// finite numbers on an OK frame is an error naming the frame. Frame times must strictly
// increase (error naming the frame).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "hw/em_log.h"
#include "imaging/io/plus_sequence.h"

namespace echoservo::imaging {

// Names of the tools with a `<Name>Transform` field in any frame (without the suffix),
// sorted: e.g. ProbeToTracker, ReferenceToTracker, StylusToTracker.
std::vector<std::string> PlusTrackerTools(const PlusSequence& sequence);

// The tool options.sensor names (with or without the Transform suffix), or the only tool
// when it is empty; throws std::invalid_argument listing the tools (with their OK frame
// counts) otherwise.
hw::EmLog PlusSequenceToEmLog(const PlusSequence& sequence, const std::filesystem::path& source,
                              const hw::EmImportOptions& options);

hw::EmLog ReadPlusEmLog(const std::filesystem::path& path, const hw::EmImportOptions& options);

// Any format: options.format, or hw::DetectEmLogFormat when it is kAuto.
hw::EmLog ReadEmLog(const std::filesystem::path& path, const hw::EmImportOptions& options);

}  // namespace echoservo::imaging
