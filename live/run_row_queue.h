// The demo's RUN rows from the servo thread, written by a thread of their own: the 1 kHz
// cycle hands each row (servo + truth at 100 Hz, EM samples, latency) to a lock-free ring
// (live/lock_free.h) and never waits for a file lock or a write(2); the writer thread drains
// the rings every `drain_period_s` into formats::RunWriter, in order per file. A row the writer
// could not take in time (a ring full: ~10 s behind) is lost and counted, never blocking the
// servo. Crash safety: a process killed at any instant loses what is queued (at most one
// drain period of rows) besides what formats::RunWriter itself may lose.
// Units and frames as in formats/run_record.h; the mode is a control::FollowerMode.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>

#include "control/target_follower.h"
#include "formats/run_record.h"
#include "live/lock_free.h"

namespace echoservo::live {

class RunRowQueue {
 public:
  // `writer` may be null (nothing is written; the calls below do nothing). Starts the thread:
  // construct it before the servo thread is raised to real time (threads inherit SCHED_FIFO).
  explicit RunRowQueue(formats::RunWriter* writer, double drain_period_s = 0.005);
  ~RunRowQueue();  // Stop()
  RunRowQueue(const RunRowQueue&) = delete;
  RunRowQueue& operator=(const RunRowQueue&) = delete;

  // Servo thread only (one producer per ring).
  void AddServo(double t_s, control::FollowerMode mode, double setpoint_mm, double base_mm,
                double tip_estimate_mm, double faults, const Eigen::Vector3d& target_mm,
                const Eigen::Vector3d& tip_mm);
  void AddEm(const formats::EmSample& s);
  void AddLatency(const formats::LatencyRecord& r);

  // Drains what is queued, stops the thread and flushes the writer (idempotent).
  void Stop();
  std::uint64_t lost() const { return lost_.load(); }  // rows overwritten before written
  // The first error the writer thread met (its rows after it are dropped); empty: none.
  std::string error() const;

 private:
  struct ServoRow {
    double t_s, setpoint_mm, base_mm, tip_estimate_mm, faults;
    double target_mm[3], tip_mm[3];
    control::FollowerMode mode;
  };
  struct EmRow {
    double t_s;
    double position_mm[3];
    bool valid;
  };
  void Drain();

  formats::RunWriter* writer_;
  double drain_period_s_;
  LossyRing<ServoRow, 2048> servo_;
  LossyRing<EmRow, 1024> em_;
  LossyRing<formats::LatencyRecord, 1024> latency_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> lost_{0};
  std::atomic<bool> failed_{false};
  std::string error_;  // written by the thread before failed_ is set
  std::thread thread_;
};

}  // namespace echoservo::live
