// Helpers for the DDS link tests (and link_test_peer): valid samples built around a time,
// a domain id of this process's own (tests run in parallel with other engineers' DDS
// tests on the same host) and polling with generous timeouts.
#pragma once

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "link/samples.h"

namespace echoservo::testing {

// 100..199 from the process id: distinct for concurrently running test processes.
inline int ProcessDomain() { return 100 + static_cast<int>(getpid() % 100); }

// A plausible estimate for frame `seq` acquired at `t_s`: every field depends on seq.
inline link::TargetEstimateSample MakeTarget(std::uint64_t seq, double t_s) {
  link::TargetEstimateSample s;
  const double k = static_cast<double>(seq % 1000);
  s.sequence_number = seq;
  s.acquisition_time_s = t_s;
  s.publication_time_s = t_s + 0.004;
  s.target_mm = {10.0 + 0.01 * k, -5.0, 60.0 + 0.5 * std::sin(k)};
  s.axis = Eigen::Vector3d(0.1, 0.2, 1.0).normalized();
  s.tip_mm = s.target_mm - 8.0 * s.axis;
  s.motion.t0_s = t_s;
  s.motion.phase0_rad = 0.25 * k;
  s.motion.frequency_hz = 1.0 + 0.001 * k;
  s.motion.offset_mm = s.axis.dot(s.target_mm);
  s.motion.drift_mm_s = 0.3;
  s.motion.cos_mm = {3.0, -0.5 + 0.001 * k, 0.2};
  s.motion.sin_mm = {0.0, 0.7, -0.1};
  s.motion.valid_until_s = t_s + 0.5;
  s.confidence = 0.9;
  return s;
}

inline link::CatheterStateSample MakeState(std::uint64_t seq, double t_s) {
  link::CatheterStateSample s;
  s.sequence_number = seq;
  s.stamp_s = t_s;
  s.mode = link::ServoMode::kTracking;
  s.faults = link::fault::kVelocityLimit;
  s.fault_count = 2 + seq;
  s.base_mm = 1.5 + 0.001 * static_cast<double>(seq);
  s.base_velocity_mm_s = -20.0;
  s.tip_estimate_mm = 1.25;
  s.setpoint_mm = 1.3;
  s.force_n = 2.5;
  s.standoff_mm = 3.0;
  s.estimate_age_s = 0.07;
  return s;
}

inline link::ServoCommandSample MakeCommand(std::uint64_t seq, double t_s,
                                            link::ServoAction action) {
  link::ServoCommandSample s;
  s.sequence_number = seq;
  s.stamp_s = t_s;
  s.action = action;
  s.standoff_mm = 2.0 + 0.1 * static_cast<double>(seq % 10);
  return s;
}

// Polls `done` every 5 ms until it holds or `timeout_s` passes (no timing assertions:
// the timeouts only bound a failing test).
template <class Done>
bool Eventually(Done done, double timeout_s = 15.0) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!done()) {
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

}  // namespace echoservo::testing
