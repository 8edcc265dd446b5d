// A synthetic moving phantom: a stand-in scanner for streaming tests, benchmarks and the
// `echoservo scanner` command when no simulated scanner is built. Not an ultrasound model.
//
// Each frame is a 160×148×208 uint8 volume (default; 0.5 mm voxels, identity direction,
// origin at 0, image frame = LPS mm) holding speckle-like noise (a fixed random field,
// values ~ 10..70, shifted by one voxel in x per frame so consecutive frames differ), a
// bright straight line (value 250, radius 1 voxel: a "catheter" from near the volume's
// (0.2, 0.5, 0.1) fraction to its centre) and a bright disc (value 200, radius 12 voxels,
// 2 voxels thick, normal z) whose centre moves on a circle of 20 voxels radius at 1 Hz in
// acquisition time. Frame n has timestamp n / rate_hz s (rate_hz ≤ 0: n / 30 s).
// Ground truth: the line (catheter_visible, axis_point_mm, axis_direction, tip_mm) and the
// disc centre (target_mm). Deterministic for a given seed. Each Next() costs one 5 MB copy
// plus drawing (~1–2 ms).
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
