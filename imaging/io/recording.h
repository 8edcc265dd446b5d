// Replaying recorded volumes as a VolumeSource: one volume file, a PLUS sequence, or a
// folder of volume files.
//
//   .mha/.mhd/.vti/.nrrd      one frame (frame_index 0, timestamp 0, identity poses);
//   *.igs.mha / *.igs.nrrd    a PLUS sequence (see plus_sequence.h): each frame a Volume
//                             with its Timestamp, FrameNumber and ImageToProbe /
//                             ProbeToReference transforms; 2D frames come out as volumes
//                             with dims.z = 1; tracker-only sequences are rejected;
//   a folder                  its volume files (by extension, non-recursive), sorted by
//                             file name, read one at a time on Next(); frame_index counts
//                             0, 1, 2, ... and timestamps are 0 (file formats carry none).
// nominal_rate_hz: (frames − 1) / (last − first timestamp) for a sequence with increasing
// timestamps, else 0. No ground truth is attached (SourceFrame::truth is empty).
// Errors at open (and from Next() for a folder's files): std::invalid_argument naming the
// file and problem.
#pragma once

#include <filesystem>
#include <memory>

#include "imaging/volume_source.h"

namespace echoservo::imaging {

std::unique_ptr<VolumeSource> OpenRecording(const std::filesystem::path& path);

// True for names ending in .igs.mha / .igs.mhd / .igs.nrrd (case-insensitive).
bool IsPlusSequenceFile(const std::filesystem::path& path);

}  // namespace echoservo::imaging
