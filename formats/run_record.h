// The RUN directory: what the live pipeline records of one tracking run (run.json,
// targets.csv, and optionally servo.csv, latency.csv, em.csv, truth.csv), read by
// `echoservo report`; RunWriter is what the pipeline and the demo call.
//
// Units and frames: times in s on the pipeline's clock (em.csv: the EM tracker's clock and
// frame, formats/em_log.h), positions in mm in the image frame (servo.csv: along the catheter
// axis). Every time column strictly increases; arrived_s ≥ acquired_s, published_s ≥
// arrived_s, applied_s ≥ arrived_s.
// Errors: the reader validates everything and throws std::invalid_argument naming the file,
// the line, the column and why.
// Details: docs/report.md#the-run-directory
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "formats/durable_file.h"
#include "formats/em_log.h"
#include "formats/run_metadata.h"

namespace echoservo::formats {

struct RunInfo {
  std::optional<double> heart_rate_hz;  // (0, 10] when given
  // The servo's tip-to-target standoff along the catheter axis, [0, 50] mm when given: the
  // report measures the tip against the target less the standoff (where the tip should be).
  std::optional<double> standoff_mm;
  std::string notes;
  RunMetadata meta;  // typed: formats/run_metadata.h
  // Keys of run.json no reader here knows (other tools'), kept as a JSON object text ("{}"
  // when none) and written back; a key of the typed metadata here is an error.
  std::string extra_json = "{}";
  // Read only: what the reader noticed but accepted (a RUN without typed metadata).
  std::vector<std::string> warnings;
};

struct TargetRecord {
  double acquired_s = 0.0;
  double arrived_s = 0.0;
  double published_s = 0.0;
  bool found = false;
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();  // catheter direction (unit)
  double confidence = 0.0;
};

struct ServoRecord {
  double t_s = 0.0;
  std::string mode;
  double setpoint_mm = 0.0;
  double base_mm = 0.0;
  double tip_estimate_mm = 0.0;
  double faults = 0.0;
};

struct LatencyRecord {
  double arrived_s = 0.0;
  double applied_s = 0.0;
};

struct TruthRecord {
  double t_s = 0.0;
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
};

// timing.json: the servo thread's real-time settings and cycle timing (written by the demo;
// live/servo_cycle_clock.h ServoTimingJson). Latencies in µs.
struct ServoTimingRecord {
  std::string realtime_summary;  // "SCHED_FIFO 80, memory locked" / "normal priority (…)"
  bool fifo = false;
  std::vector<std::string> refusals;
  double period_s = 0.0;
  std::uint64_t cycles = 0, overruns = 0, max_consecutive_overruns = 0;
  double overrun_fraction = 0.0;
  double wakeup_p50_us = 0.0, wakeup_p99_us = 0.0, wakeup_p999_us = 0.0, wakeup_max_us = 0.0;
  double cycle_p50_us = 0.0, cycle_p99_us = 0.0, cycle_p999_us = 0.0, cycle_max_us = 0.0;
  std::uint64_t deadline_holds = 0, deadline_retracts = 0;
};

// tracker.json: what became of the volumes the source acquired (written at the end of a run by
// the tracker runtime's caller: live/demo_run.cc). acquired = processed + shed; the scanner's
// lost acquisition slots (missed) were never acquired.
struct TrackerVolumeCounts {
  std::uint64_t acquired = 0;  // volumes the source acquired or read
  std::uint64_t missed = 0;    // acquisition slots the scanner lost (a late renderer)
  std::uint64_t shed = 0;      // stale volumes the tracker dropped for a newer one
  std::uint64_t skipped = 0;   // a replay's frames whose timestamp did not increase
  std::uint64_t processed = 0;
  std::uint64_t not_found = 0;  // processed, no catheter or target
};
// The tracker.json text of `counts` (one definition: the writer and ReadRunRecord).
std::string TrackerCountsJson(const TrackerVolumeCounts& counts);

struct RunRecord {
  std::filesystem::path dir;
  RunInfo info;
  std::vector<TargetRecord> targets;   // at least 2
  std::vector<ServoRecord> servo;      // empty: no servo.csv
  std::vector<LatencyRecord> latency;  // empty: no latency.csv
  std::vector<TruthRecord> truth;      // empty: no truth.csv
  ServoTimingRecord timing;            // timing.json, when has_timing
  TrackerVolumeCounts tracker;         // tracker.json, when has_tracker_counts
  bool has_servo = false, has_latency = false, has_em = false, has_truth = false;
  bool has_timing = false, has_tracker_counts = false;

  std::filesystem::path EmPath() const { return dir / "em.csv"; }
};

// Throws std::invalid_argument (missing folder, run.json or targets.csv; a bad file,
// timing.json included, naming the file and the key).
RunRecord ReadRunRecord(const std::filesystem::path& dir);

// Writes a RUN directory as the pipeline runs: run.json at once, each CSV with its header
// on its first row (em.csv and truth.csv only if rows come), rows appended in time order.
// Each file has its own lock, so the imaging and servo threads may write at the same time.
// Crash safety: every row goes to the kernel in one write(2) as it is added (no user-space
// buffer), so a process killed at any instant (kill -9) loses at most the row being added,
// and what is on disk is whole rows a reader accepts; Flush() also asks the kernel to put
// the files on the disk (fdatasync), for power loss. Throws std::invalid_argument for a
// non-finite value, a time out of order, a mode with a comma, and std::runtime_error on
// I/O errors. Files are closed by the destructor.
class RunWriter {
 public:
  // Creates `dir` (its parents too); an existing run.json there is an error.
  RunWriter(const std::filesystem::path& dir, const RunInfo& info);
  ~RunWriter();
  RunWriter(const RunWriter&) = delete;
  RunWriter& operator=(const RunWriter&) = delete;

  const std::filesystem::path& dir() const { return dir_; }
  void AddTarget(const TargetRecord& r);
  void AddServo(const ServoRecord& r);
  void AddLatency(const LatencyRecord& r);
  void AddEm(const EmSample& s);  // EM clock and frame
  void AddTruth(const TruthRecord& r);
  void Flush();

 private:
  struct File {
    std::filesystem::path path;
    std::string header;
    AppendOnlyFile file;  // opened with the first row
    std::mutex mutex;
    double last_t_s = 0.0;
    bool any = false;
  };
  void Append(File& f, double t_s, const std::string& row);

  std::filesystem::path dir_;
  File targets_, servo_, latency_, em_, truth_;
};

}  // namespace echoservo::formats
