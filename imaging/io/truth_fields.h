// Ground truth of simulated frames as per-frame fields of a PLUS sequence, so that a
// recording carries what the scanner knew (imaging/ground_truth.h) next to each volume.
//
// Fields (points in mm in the volume's image frame, directions unit vectors, flags 0/1):
//   CatheterVisible, CatheterAxisPoint "x y z", CatheterAxisDirection "x y z",
//   CatheterTip "x y z", TargetVisible, Target "x y z", and optionally AcquisitionTime (s,
//   the recording's clock: the true acquisition time of a volume stamped late).
// PLUS and 3D Slicer keep unknown per-frame fields, so the files stay standard.
#pragma once

#include <map>
#include <optional>
#include <string>

#include "imaging/ground_truth.h"

namespace echoservo::imaging {

void SetTruthFields(const FrameGroundTruth& truth, std::map<std::string, std::string>& fields);

// nullopt when the frame has no CatheterVisible field; throws std::invalid_argument naming
// the field when a value is malformed (not 3 finite numbers, a flag other than 0/1).
std::optional<FrameGroundTruth> TruthFromFields(const std::map<std::string, std::string>& fields);

}  // namespace echoservo::imaging
