// Shared fixtures of the predictor tests: synthetic mitral traces
// (control/experiments/synthetic_motion.h) and the real phantom trace
// (data/heart_motion/phantom_20hz.csv).
#pragma once

#include <string>

#include "control/experiments/synthetic_motion.h"
#include "estimation/motion_trace.h"

namespace echoservo::testing {

// The test trace: 40 s at 250 Hz, 72 bpm, 12 mm, RSA ±3 bpm, wander 3 bpm,
// 0.3 mm noise; measured at 25 vol/s by the predictor.
inline control::SyntheticMotion MitralHrvTrace(double respiration_mm = 0.0,
                                               std::uint64_t seed = 1) {
  control::SyntheticMotionOptions o = control::MitralHrvDefaults();
  o.respiration_mm = respiration_mm;
  o.seed = seed;
  return control::MakeSyntheticMotion(o);
}

inline estimation::MotionTrace TruthOf(const control::SyntheticMotion& m) {
  estimation::MotionTrace t = m.measured;
  t.position_mm = m.truth_mm;
  return t;
}

inline std::string PhantomPath() {
  return std::string(ECHOSERVO_DATA_DIR) + "/heart_motion/phantom_20hz.csv";
}

}  // namespace echoservo::testing
