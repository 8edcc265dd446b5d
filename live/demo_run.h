// The closed-loop demo: simulated scanner → tracker (detector + heartbeat EKF) → DDS link →
// 1 kHz catheter servo on the simulated catheter, whose tip moves the catheter in the
// scanner's scene; a simulated EM tracker on the tip measures the result.
//
// Real time on the host's steady clock (the pipeline clock, s since the run's start), three
// threads (scanner, tracker runtime, servo runtime: live/tracker_runtime.h,
// live/servo_runtime.h, the ones `track` and `servo` run).
// Out: tip-to-target RMS (mm) from the EM samples and from the plant's true tip over the
// scored window (report/scored_window.h, the one `echoservo report` uses); latency (ms,
// volume arrival → first servo cycle applying its estimate); counts. Units: mm, s, image frame.
// Errors: RunDemo throws std::invalid_argument for bad options, std::runtime_error when the RUN
// directory cannot be written. Details: docs/live.md#the-demo
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "control/cycle_timing.h"
#include "control/deadline_watchdog.h"
#include "control/realtime.h"
#include "hw/fault_injection.h"
#include "live/pipeline_parameters.h"

namespace echoservo::formats {
class RunWriter;
}

namespace echoservo::imaging {
class Volume;
}

namespace echoservo::live {

struct TrackedVolume;

struct DemoOptions {
  double duration_s = 20.0;   // (0, 3600]
  double rate_hz = 25.0;      // volume rate, (0, 60]
  double delay_min_s = 0.05;  // imaging delay range, [0, 1]
  double delay_max_s = 0.10;
  double heart_rate_bpm = 60.0;  // target: the mitral annulus trajectory, [30, 180]
  double target_p2p_mm = 10.0;   // its peak-to-peak excursion, (0, 20]
  // [0, 30]; down to contact (0: the tip held at the tissue's surface; overshooting, it
  // indents the tissue: live/sim_scene.h).
  double standoff_mm = LiveFollowerConfig().standoff_mm;  // the pipeline's (8 mm)
  // The figures' window from this pipeline time on; NaN (the default): the scored window
  // `echoservo report` uses too (report/scored_window.h: from when the servo follows plus
  // two heartbeats' settling).
  double metrics_start_s = std::numeric_limits<double>::quiet_NaN();
  std::uint64_t seed = 1;
  std::filesystem::path out_dir;  // the RUN directory (docs/report.md); empty: not written
  // Also record the volumes the tracker receives to out_dir/volumes.igs.mhd (+ .raw: a
  // PLUS sequence, uncompressed, 4.9 MB a volume; see imaging/io/sequence_writer.h) for
  // `echoservo track --replay`. Written on a recorder thread through a queue of
  // record_queue_volumes (imaging/io/async_sequence_writer.h): the tracker never waits
  // for the disk; a volume that finds the queue full is dropped and counted.
  bool save_volumes = false;
  std::size_t record_queue_volumes = 16;  // ≥ 1 (16: 78 MB)
  // The tracker's published motion: the EKF, or the zero-order-hold baseline.
  bool zero_order_hold = false;
  // The EKF's harmonic count, [1, 12] (TrackerNodeOptions::DefaultEkfOptions: 8, the mitral
  // shape's). It needs 2·(2·harmonics + 4) volumes before it publishes: 40 at 8, about 1.6 s
  // at 25 vol/s; fewer let a slow host (a sanitizer build) start following sooner.
  int harmonics = TrackerNodeOptions::DefaultEkfOptions().harmonics;
  // Tunable parameters by name (`--set NAME=VALUE`, live/pipeline_parameters.h), applied in
  // order over what the options above give (DemoSettings): they override standoff_mm,
  // harmonics and zero_order_hold. RUN/run.json records every value used ("settings").
  std::vector<std::pair<std::string, double>> settings;
  double sheath_id_mm = 1.59;  // the seed's water-tank catheter (its two bends)
  double guidewire_od_mm = 1.50;
  int dds_domain = 42;  // the DDS domain of the tracker → servo link (loopback only)
  // DDS-Security: a credential directory of `echoservo security init` (link/security.h);
  // the tracker's participant uses its "tracker" identity, the servo's its "servo".
  std::string secure_dir;
  // The servo thread's real-time settings (SCHED_FIFO, CPU, locked memory: control/realtime.h)
  // and its deadline watchdog's limits; refusals by the system are logged once and the
  // servo runs as an ordinary thread.
  control::RealtimeOptions realtime;
  control::DeadlineWatchdogConfig watchdog;
  // Slow hardware reads on purpose (hw::FaultKind::kSlowRead on the servo's hardware), to
  // provoke the deadline watchdog.
  std::vector<hw::InjectedFault> slow_reads;
  std::function<void(const std::string&)> log;  // progress lines; may be null
  // A live EM stream (`--em-connect`, a PLUS server) writes em.csv instead of the simulated
  // EM tracker, whose samples still give tip_to_target_rms_mm and em_samples. Called once
  // the RUN writer exists (null without out_dir); returns the function that stops the
  // stream, called before the writer goes (an exception included).
  std::function<std::function<void()>(formats::RunWriter*)> external_em;
  // Each volume the tracker processed: its result, the volume, and its acquisition time on
  // the system clock (s since the Unix epoch: pipeline time + the pipeline clock's offset,
  // measured once at the start). Called on the tracker's thread right after Process, so it
  // must not block (`--igtl-serve`: DetectionServer::Publish). May be null.
  std::function<void(const TrackedVolume&, const imaging::Volume&, double acquired_unix_s)>
      on_tracked;
  // Throws std::invalid_argument naming the option.
  void Validate() const;
};

struct LatencyStats {
  double p50_ms = 0.0, p99_ms = 0.0, max_ms = 0.0;
  std::uint64_t count = 0;
};

struct DemoResult {
  double tip_to_target_rms_mm = 0.0;       // EM-measured, over the scored window
  double true_tip_to_target_rms_mm = 0.0;  // plant truth, over the scored window
  // The scored window (report/scored_window.h): its start (NaN: nothing scored) and why.
  double scored_from_s = 0.0;
  std::string scored_window;
  LatencyStats latency;              // arrival → setpoint applied
  std::uint64_t volumes = 0;         // acquired
  std::uint64_t detected = 0;        // volumes with a catheter found
  std::uint64_t dropped_frames = 0;  // not detected, skipped by a late tracker, or not acquired
  std::uint64_t missed_acquisitions = 0;     // acquisition slots lost to a late renderer
  std::uint64_t shed_volumes = 0;            // stale volumes the tracker dropped for a newer one
  std::uint64_t tracker_errors = 0;          // volumes the tracker could not process (logged)
  std::uint64_t volumes_recorded = 0;        // --save-volumes: volumes written to volumes.igs.mhd
  std::uint64_t volumes_record_dropped = 0;  // --save-volumes: not recorded (queue full, error)
  std::string record_error;                  // --save-volumes: why the recording stopped
  std::uint64_t estimates_accepted = 0;      // by the servo
  std::uint64_t estimates_rejected = 0;
  // Of those, rejected at the link (failed validation) and by the follower: non-finite, out
  // of range, out of time (acquired after published, published in the future, older than
  // the stale limit + 1 s, or not newer than the estimate in use), low confidence.
  std::uint64_t rejected_link = 0, rejected_non_finite = 0, rejected_range = 0, rejected_time = 0,
                rejected_confidence = 0;
  std::uint64_t em_samples = 0, em_dropouts = 0;
  std::uint64_t servo_cycles = 0, servo_overruns = 0;  // overrun: ended after the next deadline
  control::RealtimeStatus realtime;                    // what the system granted the servo thread
  control::CycleTimingReport timing;                   // wake-up latency, cycle duration, overruns
  std::uint64_t deadline_holds = 0, deadline_retracts = 0;  // the deadline watchdog's
  std::string timing_json;             // live::ServoTimingJson (also RUN/timing.json)
  std::uint64_t limit_faults = 0;      // limiter interventions counted as faults (clamps)
  std::uint64_t limit_violations = 0;  // cycles commanding outside a limit: must be 0
  std::uint64_t resumes = 0;           // following resumed after a watchdog retraction
  std::uint64_t stale_events = 0;      // the follower found its estimate stale (hold)
  // Close approach: volumes processed by the tracker; of them, those whose target was found,
  // those acquired with the tip at or past the tissue's surface (truth: touching or
  // indenting it), those the detector reported as contact, and of the touching ones, those
  // reported as contact; and those reported as contact with the tip more than 0.5 mm short
  // of the surface (the contact tolerance is 0.3 mm, tracking/axis_profile.h).
  std::uint64_t tracked_volumes = 0, target_found = 0;
  std::uint64_t contact_true = 0, contact_reported = 0, contact_true_reported = 0;
  std::uint64_t contact_reported_apart = 0;
  int ekf_harmonics = 0;
  double ekf_rate_hz = 0.0;
};

// The pipeline's settings RunDemo runs with: PipelineSettings{} (live/pipeline_parameters.h)
// with `harmonics`, `zero_order_hold` and `standoff_mm`, the simulated catheter's servo for
// the options' catheter and seed (live/sim_catheter.h), then `settings`. Throws
// std::invalid_argument naming a bad --set.
PipelineSettings DemoSettings(const DemoOptions& options);

// Runs the demo for options.duration_s of real time. Throws std::invalid_argument for bad
// options, std::runtime_error when the RUN directory cannot be written.
DemoResult RunDemo(const DemoOptions& options);

}  // namespace echoservo::live
