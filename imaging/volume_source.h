// A stream of 3D ultrasound volumes: the simulated scanner, a recording being replayed,
// or an OpenIGTLink connection. Consumers (the scanner server, the tracker) pull frames
// in order; each carries its acquisition timestamp (s) and frame index, and optionally
// the ground truth a simulator knows.
#pragma once

#include <optional>

#include "imaging/ground_truth.h"
#include "imaging/volume.h"

namespace echoservo::imaging {

struct SourceFrame {
  Volume volume;
  std::optional<FrameGroundTruth> truth;  // known for simulated frames only
};

class VolumeSource {
 public:
  virtual ~VolumeSource() = default;
  // The next frame, or nullopt at the end of the stream.
  virtual std::optional<SourceFrame> Next() = 0;
  // Nominal frame rate (vol/s), 0 when unknown.
  virtual double nominal_rate_hz() const = 0;
};

}  // namespace echoservo::imaging
