// Replaying recorded volumes as a VolumeSource: one volume file, a PLUS sequence, or a
// folder of volume files.
//
// A volume file gives one frame (index 0, time 0, identity poses); a PLUS sequence gives its
// frames with their Timestamp (s), FrameNumber and ImageToProbe / ProbeToReference
// transforms (tracker-only sequences are rejected); a folder gives its volume files sorted
// by name (times 0). nominal_rate_hz is 0 unless a sequence's timestamps increase. No
// ground truth is attached. Errors at open (and from Next() for a folder's files):
// std::invalid_argument naming the file and the problem.
// Details: docs/imaging.md#replaying-recordings-imagingiorecordingh
#pragma once

#include <filesystem>
#include <memory>

#include "imaging/volume_source.h"

namespace echoservo::imaging {

std::unique_ptr<VolumeSource> OpenRecording(const std::filesystem::path& path);

// True for names ending in .igs.mha / .igs.mhd / .igs.nrrd (case-insensitive).
bool IsPlusSequenceFile(const std::filesystem::path& path);

}  // namespace echoservo::imaging
