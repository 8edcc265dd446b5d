#include "live/demo_run.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "formats/durable_file.h"
#include "formats/run_dir_guard.h"
#include "formats/run_record.h"
#include "hw/fault_injection.h"
#include "hw/sim_em_tracker.h"
#include "link/dds_link.h"
#include "link/security.h"
#include "live/lock_free.h"
#include "live/pipeline_clock.h"
#include "live/pipeline_parameters.h"
#include "live/run_row_queue.h"
#include "live/servo_cycle_clock.h"
#include "live/servo_node.h"
#include "live/servo_runtime.h"
#include "live/sim_catheter.h"
#include "live/sim_scene.h"
#include "live/tracker_node.h"
#include "live/tracker_runtime.h"
#include "live/tracker_source.h"
#include "report/accuracy_report.h"
#include "report/scored_window.h"

namespace echoservo::live {
namespace {

// Arrival times of the published volumes by sequence number: the latency's start, which
// the DDS sample does not carry (in-process bookkeeping of the demo only). The tracker
// thread adds through a lock-free ring; the servo thread keeps the newest 256 in its own
// array, so neither ever waits for the other.
class Arrivals {
 public:
  void Add(std::uint64_t seq, double arrived_s) { ring_.Push({seq, arrived_s}); }  // tracker
  std::optional<double> Find(std::uint64_t seq) {                                  // servo
    ring_.Drain([this](const Arrival& a) { seen_[next_++ % seen_.size()] = a; });
    for (const Arrival& a : seen_)
      if (a.seq == seq && a.seq != 0) return a.arrived_s;
    return std::nullopt;
  }

 private:
  struct Arrival {
    std::uint64_t seq = 0;  // sequence numbers start at 1
    double arrived_s = 0.0;
  };
  LossyRing<Arrival, 256> ring_;
  std::array<Arrival, 256> seen_{};
  std::size_t next_ = 0;
};

std::string DemoFmt(const char* f, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

// The dds.sec.* properties of `role` in --secure DIR (errors name the flag and the file).
std::vector<std::pair<std::string, std::string>> SecureProperties(const std::string& dir,
                                                                  const std::string& role) {
  try {
    return link::SecurityProperties(link::CheckSecurityDir(dir, role));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("demo: --secure " + dir + " (identity '" + role +
                                "'): " + e.what());
  }
}

}  // namespace

void DemoOptions::Validate() const {
  auto bad = [](const std::string& f, const std::string& why) {
    throw std::invalid_argument("demo: " + f + " " + why);
  };
  if (!(duration_s > 0 && duration_s <= 3600)) bad("--duration", "must be in (0, 3600] s");
  if (!(rate_hz > 0 && rate_hz <= 60)) bad("--rate", "must be in (0, 60] vol/s");
  if (!(delay_min_s >= 0 && delay_max_s >= delay_min_s && delay_max_s <= 1))
    bad("--delay", "must satisfy 0 ≤ min ≤ max ≤ 1 s");
  if (!(heart_rate_bpm >= 30 && heart_rate_bpm <= 180))
    bad("--heart-rate", "must be in [30, 180] bpm");
  if (!(target_p2p_mm > 0 && target_p2p_mm <= 20)) bad("--target-p2p", "must be in (0, 20] mm");
  if (!(standoff_mm >= 0 && standoff_mm <= 30)) bad("--standoff", "must be in [0, 30] mm");
  if (!(harmonics >= 1 && harmonics <= 12)) bad("--harmonics", "must be in [1, 12]");
  if (!std::isnan(metrics_start_s) && !(metrics_start_s >= 0 && metrics_start_s < duration_s))
    bad("--metrics-start", "must be in [0, duration)");
  if (save_volumes && out_dir.empty()) bad("--save-volumes", "needs --out RUN");
  if (record_queue_volumes < 1) bad("--save-volumes", "needs a recorder queue of ≥ 1 volume");
  if (!(dds_domain >= 0 && dds_domain <= 232)) bad("--dds-domain", "must be in [0, 232]");
  if (!(guidewire_od_mm > 0 && sheath_id_mm > guidewire_od_mm && sheath_id_mm <= 5))
    bad("--sheath-id/--guidewire-od", "must satisfy 0 < guidewire < sheath ≤ 5 mm");
  for (const auto& [name, value] : settings) {  // names and bounds; combinations: DemoSettings
    try {
      CheckValue(RequireParameter(name), value);
    } catch (const std::invalid_argument& e) {
      bad("--set", e.what());
    }
  }
  realtime.Validate();
  watchdog.Validate(1e-3);    // the simulated catheter's servo period (live/sim_catheter.h)
  if (!secure_dir.empty()) {  // before the scene is built: a bad directory fails at once
    SecureProperties(secure_dir, "tracker");
    SecureProperties(secure_dir, "servo");
  }
}

PipelineSettings DemoSettings(const DemoOptions& o) {
  PipelineSettings s;
  if (o.zero_order_hold) s.tracker.predictor = TargetPredictor::kZeroOrderHold;
  s.tracker.ekf.harmonics = o.harmonics;
  s.tracker.ekf.max_harmonics = std::max(s.tracker.ekf.max_harmonics, o.harmonics);
  s.follower.standoff_mm = o.standoff_mm;
  s.servo = MakeSimCatheter(o.sheath_id_mm, o.guidewire_od_mm, o.seed).servo;
  if (!o.settings.empty()) {
    try {
      Apply(o.settings, s);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("demo: --set: ") + e.what());
    }
  }
  return s;
}

namespace {

// The tracker's side of the demo, on the tracker runtime's thread: the volume's arrival for the
// latency, the close-approach counters against the scene's truth, and the caller's sink.
struct DemoTrackerSink {
  const DemoOptions& o;
  SimScene& scene;
  Arrivals& arrivals;
  std::function<void(const std::string&)> log;
  std::atomic<std::uint64_t> tracked{0}, target_found{0}, contact_true{0}, contact_reported{0},
      contact_true_reported{0}, contact_reported_apart{0};

  void operator()(const TrackedVolume& r, const SourceVolume& v, double unix_offset_s) {
    if (r.published) arrivals.Add(r.sequence, v.arrived_s);
    if (o.on_tracked) o.on_tracked(r, v.volume, v.stamp_s + unix_offset_s);
    if (!r.error.empty()) return;
    ++tracked;
    const tracking::CatheterDetection& det = r.detection;
    if (det.found && det.target_found) ++target_found;
    const double past_mm = scene.TipPastSurfaceMm(v.stamp_s);
    const bool touching = past_mm >= 0.0;
    const bool reported = det.found && det.target_found && det.contact;
    contact_true += touching;
    contact_reported += reported;
    contact_true_reported += touching && reported;
    contact_reported_apart += reported && past_mm < -0.5;
  }
};

// The servo's side of the demo, once per cycle on the servo thread: latency, the scene's tip,
// the EM samples, the RUN rows and the scored sums. Allocation-free once warm.
class DemoServoBook {
 public:
  DemoServoBook(const DemoOptions& o, SimScene& scene, hw::SimulatedCatheter& plant,
                ServoNode& servo, Arrivals& arrivals, RunRowQueue& rows, double heart_rate_hz)
      : o_(o),
        scene_(scene),
        plant_(plant),
        servo_(servo),
        arrivals_(arrivals),
        rows_(rows),
        em_(scene.em_options(), 0.0),
        em_to_image_(scene.em_to_image()),
        heart_rate_hz_(heart_rate_hz) {
    latency_ms_.reserve(static_cast<std::size_t>(o.duration_s * o.rate_hz) + 16);
    // A window the user gave (--metrics-start) holds from the start; else it opens once
    // servo.csv's first "following" row is written (report/scored_window.h).
    if (std::isfinite(o.metrics_start_s))
      window_ = report::GivenWindow(o.metrics_start_s, "demo --metrics-start");
  }

  void Cycle(std::uint64_t k, double t, const ServoCycle& c, const PipelineClock& clock,
             std::uint64_t acquired, std::uint64_t measured) {
    if (c.applied_sequence) pending_ = std::make_pair(*c.applied_sequence, clock.Now());
    if (pending_) NoteLatency();
    const double tip_true = plant_.truth().tip_mm;
    scene_.SetPlantTip(t, tip_true);
    const Eigen::Vector3d tip_img = scene_.TipImage(tip_true);
    const control::FollowerMode mode = servo_.follower().mode();
    if (k % 10 == 0) {  // a servo.csv row; the first "following" one opens the window
      rows_.AddServo(t, mode, c.record.reference_mm, c.record.base_mm, c.record.tip_mm,
                     static_cast<double>(servo_.stats().fault_events), scene_.TargetImage(t),
                     tip_img);
      if (!window_ && mode == control::FollowerMode::kFollowing)
        window_ = report::WindowAfterFollowing(t, heart_rate_hz_);
    }
    if (window_ && t >= window_->from_s) true_.Add((tip_img - scene_.DesiredTip(t)).squaredNorm());
    while (em_.next_sample_s() <= t) {
      const formats::EmSample r = em_.Sample(tip_img);
      if (!o_.external_em) rows_.AddEm(r);
      const double t_pipeline = r.t_s - scene_.em_options().clock_offset_s;
      if (r.valid && window_ && t_pipeline >= window_->from_s)
        em_sq_.Add((em_to_image_ * r.position_mm - scene_.DesiredTip(t_pipeline)).squaredNorm());
    }
    if (k % 1000 == 0 && k > 0 && o_.log)  // once a second: a line of progress
      o_.log(DemoFmt("t %.0f s: mode %s, volumes %llu, detected %llu", t,
                     control::ToString(mode).c_str(), static_cast<unsigned long long>(acquired),
                     static_cast<unsigned long long>(measured)));
  }

  void Fill(DemoResult& r) const {
    r.tip_to_target_rms_mm = em_sq_.Rms();
    r.true_tip_to_target_rms_mm = true_.Rms();
    r.scored_from_s = window_ ? window_->from_s : std::numeric_limits<double>::quiet_NaN();
    r.scored_window = window_ ? window_->reason : "nothing scored: the servo never followed";
    r.em_samples = em_.samples();
    r.em_dropouts = em_.dropouts();
    r.latency.count = latency_ms_.size();
    if (!latency_ms_.empty()) {
      r.latency.p50_ms = report::Percentile(latency_ms_, 0.5);
      r.latency.p99_ms = report::Percentile(latency_ms_, 0.99);
      r.latency.max_ms = report::Percentile(latency_ms_, 1.0);
    }
  }
  std::uint64_t latency_out_of_order() const { return latency_out_of_order_; }

 private:
  struct SumSq {
    double sum = 0.0;
    std::uint64_t n = 0;
    void Add(double sq) { sum += sq, ++n; }
    double Rms() const { return n ? std::sqrt(sum / static_cast<double>(n)) : 0.0; }
  };

  // The newest applied estimate whose arrival the tracker has not noted yet (the servo can
  // apply an estimate before the tracker thread is back from Publish): its latency is taken
  // once the arrival is known, with the time it was applied. latency.csv's rows go in arrival
  // order; an estimate applied after a newer one's (seen once under the sanitizers' load) is
  // counted, not written out of order.
  void NoteLatency() {
    const std::optional<double> arrived = arrivals_.Find(pending_->first);
    if (!arrived) return;
    const double applied = pending_->second;
    if (*arrived > last_latency_arrived_s_) {
      latency_ms_.push_back(1e3 * (applied - *arrived));
      rows_.AddLatency({*arrived, applied});
      last_latency_arrived_s_ = *arrived;
    } else {
      ++latency_out_of_order_;
    }
    pending_.reset();
  }

  const DemoOptions& o_;
  SimScene& scene_;
  hw::SimulatedCatheter& plant_;
  ServoNode& servo_;
  Arrivals& arrivals_;
  RunRowQueue& rows_;
  hw::SimEmTracker em_;
  Eigen::Isometry3d em_to_image_;
  double heart_rate_hz_;
  std::optional<report::ScoredWindow> window_;
  SumSq em_sq_, true_;
  std::vector<double> latency_ms_;
  std::optional<std::pair<std::uint64_t, double>> pending_;  // sequence, applied_s
  double last_latency_arrived_s_ = -std::numeric_limits<double>::infinity();
  std::uint64_t latency_out_of_order_ = 0;
};

// The tracker runtime on its own thread: the simulated scanner → node → link, RUN, recorder,
// and the demo's sink. However the demo is left, the thread is stopped and joined first.
struct DemoTracker {
  static TrackerRuntimeOptions Options(const DemoOptions& o, const PipelineSettings& settings,
                                       const PipelineClock& clock, link::TargetPublisher& pub,
                                       formats::RunWriter* writer, DemoTrackerSink& sink) {
    TrackerRuntimeOptions tro;
    tro.node = settings.tracker;
    tro.node.link_offset_s = clock.link_offset_s();
    tro.publisher = &pub;
    tro.writer = writer;
    if (o.save_volumes) tro.record_to = o.out_dir / "volumes.igs.mhd";
    tro.record_queue_volumes = o.record_queue_volumes;
    tro.log = [log = sink.log](const std::string& s) {
      if (log) log("tracker: " + s);
    };
    const double unix_offset_s = clock.link_offset_s();
    tro.on_tracked = [&sink, unix_offset_s](const TrackedVolume& r, const SourceVolume& v, double) {
      sink(r, v, unix_offset_s);
    };
    return tro;
  }
  DemoTracker(const DemoOptions& o, const PipelineSettings& settings, SimScene& scene,
              const PipelineClock& clock, link::TargetPublisher& pub, formats::RunWriter* writer,
              DemoTrackerSink& sink)
      : runtime(Options(o, settings, clock, pub, writer, sink)),
        scanner(scene, clock, {o.rate_hz, o.delay_min_s, o.delay_max_s, o.duration_s, o.seed}),
        thread([this] { result = runtime.Run(scanner); }) {}
  ~DemoTracker() {
    scanner.Stop();
    if (thread.joinable()) thread.join();
  }
  // Stops the scanner, waits for the runtime (the recording closed) and returns its result.
  TrackerRunResult Finish() {
    scanner.Stop();
    if (thread.joinable()) thread.join();
    return result;
  }
  TrackerRuntime runtime;
  SimScannerSource scanner;
  TrackerRunResult result;
  std::thread thread;
};

// The DDS link, loopback only; samples carry the system clock: pipeline + link_offset_s.
struct DemoLink {
  static link::ParticipantOptions Options(const DemoOptions& o, const std::string& role) {
    link::ParticipantOptions po;
    po.domain_id = o.dds_domain;
    po.loopback_only = true;
    po.name = "echoservo_demo_" + role;
    if (!o.secure_dir.empty()) po.properties = SecureProperties(o.secure_dir, role);
    return po;
  }
  explicit DemoLink(const DemoOptions& o)
      : tracker(Options(o, "tracker")), servo(Options(o, "servo")), target_pub(tracker) {}
  link::Participant tracker, servo;
  link::TargetPublisher target_pub;
};

// The servo: the simulated catheter, read through a slow driver on purpose (slow_reads).
struct DemoServo {
  DemoServo(const DemoOptions& o, const PipelineSettings& settings, const PipelineClock& clock,
            link::Participant& participant)
      : catheter(MakeSimCatheter(o.sheath_id_mm, o.guidewire_od_mm, o.seed)),
        options([&] {
          ServoNodeOptions so;
          so.follower = settings.follower;
          so.auto_enable = true;  // the demo resumes by itself; a clinic waits for ENABLE
          so.link_offset_s = clock.link_offset_s();
          so.watchdog = o.watchdog;
          return so;
        }()),
        slow_hw(o.slow_reads.empty()
                    ? nullptr
                    : std::make_unique<hw::FaultInjectingHardware>(*catheter.plant, o.slow_reads)),
        node(slow_hw ? static_cast<hw::HardwareInterface&>(*slow_hw) : *catheter.plant,
             settings.servo, std::move(catheter.compensator), options, &participant) {}
  SimCatheter catheter;
  ServoNodeOptions options;
  std::unique_ptr<hw::FaultInjectingHardware> slow_hw;
  ServoNode node;
};

// The RUN directory's run.json (formats/run_record.h): the typed metadata of this run.
formats::RunInfo DemoRunInfo(const DemoOptions& o, const PipelineSettings& settings,
                             const SimScene& scene, const PipelineClock& clock) {
  formats::RunInfo info;
  info.heart_rate_hz = o.heart_rate_bpm / 60.0;
  info.standoff_mm = settings.follower.standoff_mm;
  info.meta.source = "echoservo demo";
  info.meta.seed = o.seed;
  info.meta.duration_s = o.duration_s;
  info.meta.em_to_image = scene.em_to_image();
  info.meta.time_base = formats::RunTimeBase::kPipeline;
  info.meta.pipeline_to_unix_s = clock.link_offset_s();
  info.meta.settings = AllValues(settings);  // every parameter (live/pipeline_parameters.h)
  return info;
}

void FillDemoCounts(const ServoNode& servo, const TrackerRunResult& tr, const DemoTrackerSink& sink,
                    DemoResult& result) {
  const ServoNodeStats& ss = servo.stats();
  result.servo_cycles = ss.cycles;
  result.servo_overruns = result.timing.overruns;
  result.deadline_holds = ss.deadline_holds;
  result.deadline_retracts = ss.deadline_retracts;
  result.limit_faults = ss.limit_interventions;
  result.limit_violations = ss.limit_violations;
  result.resumes = ss.resumes;
  const control::FollowerCounters& fc = servo.follower().counters();
  result.stale_events = fc.stale_events;
  result.estimates_accepted = ss.estimates_accepted;
  result.rejected_link = servo.target_link_stats().validation.total_rejected();
  result.estimates_rejected = ss.estimates_rejected + result.rejected_link;
  result.rejected_non_finite = fc.rejected_non_finite;
  result.rejected_range = fc.rejected_range;
  result.rejected_time = fc.rejected_time;
  result.rejected_confidence = fc.rejected_confidence;
  result.tracked_volumes = sink.tracked;
  result.target_found = sink.target_found;
  result.contact_true = sink.contact_true;
  result.contact_reported = sink.contact_reported;
  result.contact_true_reported = sink.contact_true_reported;
  result.contact_reported_apart = sink.contact_reported_apart;
  result.volumes = tr.volumes.acquired;
  result.detected = tr.stats.measured;
  result.missed_acquisitions = tr.volumes.missed;
  result.shed_volumes = tr.volumes.shed;
  result.dropped_frames = tr.volumes.shed + tr.volumes.not_found + tr.volumes.missed;
  result.tracker_errors = tr.stats.errors;
  result.volumes_recorded = tr.recorder.written;
  result.volumes_record_dropped = tr.recorder.dropped;
  result.record_error = tr.recorder.error;
}

}  // namespace

DemoResult RunDemo(const DemoOptions& o) {
  o.Validate();
  auto log = [&](const std::string& s) {
    if (o.log) o.log(s);
  };
  const PipelineSettings settings = DemoSettings(o);  // the options' own, then --set
  SimScene scene(
      {o.rate_hz, o.heart_rate_bpm, o.target_p2p_mm, settings.follower.standoff_mm, o.seed});
  const PipelineClock clock(0.3);
  // The RUN directory: run.json now, the streams as they come. If the demo fails, what it
  // created there is removed so a retry with the same --out works.
  formats::RunDirGuard run_guard(o.out_dir);
  std::unique_ptr<formats::RunWriter> writer;
  if (!o.out_dir.empty())
    writer =
        std::make_unique<formats::RunWriter>(o.out_dir, DemoRunInfo(o, settings, scene, clock));
  // The live EM stream's rows go to the writer: stopped before it is destroyed.
  struct ExternalEm {
    std::function<void()> stop;
    ~ExternalEm() {
      if (stop) stop();
    }
  } external_em;
  if (o.external_em) external_em.stop = o.external_em(writer.get());

  DemoLink dds(o);
  DemoServo servo_side(o, settings, clock, dds.servo);
  ServoNode& servo = servo_side.node;
  hw::SimulatedCatheter& plant = *servo_side.catheter.plant;
  const ServoNodeOptions& so = servo_side.options;
  link::TargetPublisher& target_pub = dds.target_pub;
  target_pub.WaitForSubscribers(1, 5.0);

  // The tracker runtime on its own thread: the simulated scanner → node → link, RUN, recorder.
  Arrivals arrivals;
  DemoTrackerSink sink{o, scene, arrivals, log};
  DemoTracker tracker(o, settings, scene, clock, target_pub, writer.get(), sink);
  SimScannerSource& scanner = tracker.scanner;

  // The servo's RUN rows go to the disk from a thread of their own (created before the servo
  // thread is raised to real time), then the servo runtime on this thread.
  RunRowQueue rows(writer.get());
  DemoServoBook book(o, scene, plant, servo, arrivals, rows, o.heart_rate_bpm / 60.0);
  ServoRuntimeOptions sro;
  sro.clock = ServoClock::kRealtime;
  sro.pipeline_clock = &clock;
  sro.realtime = o.realtime;
  sro.duration_s = o.duration_s;
  DemoResult result;
  const ServoRunResult sr =
      ServoRuntime(servo, sro)
          .Run(
              nullptr,
              [&](std::uint64_t k, double t, const ServoCycle& c) {
                // The progress line's counts: atomics (the node's own stats are the tracker
                // thread's).
                book.Cycle(k, t, c, clock, scanner.counts().acquired, sink.target_found.load());
              },
              [&log](const control::RealtimeStatus& rt) {
                for (const std::string& r : rt.refusals) log("real time: " + r);
                log("real time: " + rt.Summary());
              });
  const TrackerRunResult tracked = tracker.Finish();
  servo.WaitStatesPublished(1.0);  // the publisher thread's last state, counted
  rows.Stop();                     // the servo's rows on disk (and flushed)
  if (!rows.error().empty())
    throw std::runtime_error("demo: writing the RUN rows: " + rows.error());
  if (rows.lost() > 0)
    log(DemoFmt("RUN rows: %llu row(s) lost (the row writer fell behind the servo)",
                static_cast<unsigned long long>(rows.lost())));
  if (book.latency_out_of_order() > 0)
    log(DemoFmt("latency: %llu estimate(s) applied after a newer one, not scored",
                static_cast<unsigned long long>(book.latency_out_of_order())));

  result.realtime = sr.realtime;
  result.timing = sr.timing;
  FillDemoCounts(servo, tracked, sink, result);
  book.Fill(result);
  result.ekf_harmonics = tracker.runtime.node().ekf().harmonics();
  result.ekf_rate_hz = tracker.runtime.node().ekf().rate_hz();
  result.timing_json = ServoTimingJson(result.realtime, result.timing, so.watchdog,
                                       result.deadline_holds, result.deadline_retracts);
  if (!o.out_dir.empty())
    formats::ReplaceFileContents(o.out_dir / "timing.json", result.timing_json + "\n");
  if (external_em.stop) external_em.stop();  // its last rows in before the flush
  if (writer) writer->Flush();
  run_guard.Keep();
  return result;
}

}  // namespace echoservo::live
