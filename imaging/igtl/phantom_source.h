// A synthetic moving phantom: a stand-in scanner for streaming tests, benchmarks and the
// `echoservo scanner` command when no simulated scanner is built. Not an ultrasound model.
//
// Each frame: a uint8 volume (default 160×148×208, 0.5 mm voxels, identity direction, image
// frame = LPS mm) of shifting noise, a bright straight line (the "catheter") and a bright
// disc moving on a circle at 1 Hz (the "target"), with their ground truth. Frame n has
// timestamp n / rate_hz s (rate_hz ≤ 0: n / 30 s). Deterministic for a given seed.
// Details: docs/openigtlink.md#the-synthetic-phantom-imagingigtlphantom_sourceh
#pragma once

#include <cstdint>
#include <vector>

#include "imaging/volume_source.h"

namespace echoservo::imaging::openigtlink {

struct PhantomOptions {
  Eigen::Vector3i dims{160, 148, 208};
  double spacing_mm = 0.5;
  double rate_hz = 30.0;          // nominal rate reported to servers (0: unknown)
  std::int64_t frame_count = -1;  // < 0: endless
  std::uint32_t seed = 1;
};

class PhantomSource : public VolumeSource {
 public:
  explicit PhantomSource(PhantomOptions options = {});
  std::optional<SourceFrame> Next() override;
  double nominal_rate_hz() const override { return options_.rate_hz; }

 private:
  PhantomOptions options_;
  VolumeGeometry geometry_;
  std::vector<std::uint8_t> noise_;  // one frame of noise plus one extra row
  std::int64_t index_ = 0;
};

}  // namespace echoservo::imaging::openigtlink
