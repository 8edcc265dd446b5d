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
#include "imaging/io/async_sequence_writer.h"
#include "link/dds_link.h"
#include "link/security.h"
#include "live/delayed_scanner.h"
#include "live/lock_free.h"
#include "live/pipeline_clock.h"
#include "live/pipeline_parameters.h"
#include "live/run_row_queue.h"
#include "live/servo_cycle_clock.h"
#include "live/servo_node.h"
#include "live/sim_catheter.h"
#include "live/sim_scene.h"
#include "live/tracker_node.h"
#include "report/accuracy_report.h"

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

std::string Fmt(const char* f, auto... args) {
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
  if (!(metrics_start_s >= 0 && metrics_start_s < duration_s))
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
  s.follower.offset_gain = 0.05;
  s.follower.estimate_scale = true;  // image mm = 1540/1482 catheter mm in the water tank
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

DemoResult RunDemo(const DemoOptions& o) {
  o.Validate();
  auto log = [&](const std::string& s) {
    if (o.log) o.log(s);
  };
  // The tracker's, follower's and servo's settings: the options' own, then --set.
  const PipelineSettings settings = DemoSettings(o);
  const double standoff_mm = settings.follower.standoff_mm;

  SimScene scene({o.rate_hz, o.heart_rate_bpm, o.target_p2p_mm, standoff_mm, o.seed});
  const Eigen::Isometry3d em_to_image = scene.em_to_image();

  // The RUN directory (formats/run_record.h): run.json now, the streams as they come. If the
  // demo fails, what it created there is removed so a retry with the same --out works.
  formats::RunDirGuard run_guard(o.out_dir);
  std::unique_ptr<formats::RunWriter> writer;
  if (!o.out_dir.empty()) {
    formats::RunInfo info;
    info.heart_rate_hz = o.heart_rate_bpm / 60.0;
    info.standoff_mm = standoff_mm;
    info.meta.source = "echoservo demo";
    info.meta.seed = o.seed;
    info.meta.duration_s = o.duration_s;
    info.meta.em_to_image = em_to_image;
    info.meta.time_base = formats::RunTimeBase::kPipeline;
    info.meta.settings = AllValues(settings);  // every parameter (live/pipeline_parameters.h)
    writer = std::make_unique<formats::RunWriter>(o.out_dir, info);
  }
  // The live EM stream's rows go to the writer: stopped before it is destroyed.
  struct ExternalEm {
    std::function<void()> stop;
    ~ExternalEm() {
      if (stop) stop();
    }
  } external_em;
  if (o.external_em) external_em.stop = o.external_em(writer.get());

  // The DDS link (link/dds_link.h): the tracker's and the servo's participants, loopback
  // only. Samples carry the shared (system) clock: pipeline time + link_offset_s.
  link::ParticipantOptions po;
  po.domain_id = o.dds_domain;
  po.loopback_only = true;
  po.name = "echoservo_demo_tracker";
  if (!o.secure_dir.empty()) po.properties = SecureProperties(o.secure_dir, "tracker");
  link::Participant tracker_participant(po);
  po.name = "echoservo_demo_servo";
  if (!o.secure_dir.empty()) po.properties = SecureProperties(o.secure_dir, "servo");
  link::Participant servo_participant(po);
  link::TargetPublisher target_pub(tracker_participant);

  const PipelineClock clock(0.3);
  TrackerNodeOptions to = settings.tracker;
  to.link_offset_s = clock.link_offset_s();
  // The volumes as the tracker receives them, written on the recorder's own thread: the
  // tracker hands each over after publishing and never waits for the disk (a full queue
  // drops the volume, counted).
  std::unique_ptr<imaging::AsyncSequenceWriter> recorder;
  if (o.save_volumes)
    recorder = std::make_unique<imaging::AsyncSequenceWriter>(o.out_dir / "volumes.igs.mhd",
                                                              o.record_queue_volumes);
  TrackerNode tracker(to, &target_pub, writer.get());
  SimCatheter catheter = MakeSimCatheter(o.sheath_id_mm, o.guidewire_od_mm, o.seed);
  catheter.servo = settings.servo;
  hw::SimulatedCatheter& plant = *catheter.plant;
  ServoNodeOptions so;
  so.follower = settings.follower;
  // The operator's enable once tracking delivers, and again after a retraction (the demo
  // resumes by itself; a clinical system waits for the operator's ENABLE command).
  so.auto_enable = true;
  so.link_offset_s = clock.link_offset_s();
  so.watchdog = o.watchdog;
  // A slow driver on purpose (slow_reads): the servo reads the plant through it.
  std::optional<hw::FaultInjectingHardware> slow_hw;
  if (!o.slow_reads.empty()) slow_hw.emplace(plant, o.slow_reads);
  hw::HardwareInterface& servo_hw = slow_hw ? static_cast<hw::HardwareInterface&>(*slow_hw) : plant;
  ServoNode servo(servo_hw, catheter.servo, std::move(catheter.compensator), so,
                  &servo_participant);
  target_pub.WaitForSubscribers(1, 5.0);

  DemoResult result;
  std::atomic<bool> stop{false};
  Arrivals arrivals;
  DelayedScanner scanner(scene, clock,
                         {o.rate_hz, o.delay_min_s, o.delay_max_s, o.duration_s, o.seed});

  // Tracker: the newest delivered volume → detector → EKF → link.
  std::atomic<std::uint64_t> tracked_volumes{0}, target_found{0}, contact_true{0},
      contact_reported{0}, contact_true_reported{0}, contact_reported_apart{0};
  std::thread tracker_thread([&] {
    while (true) {
      std::optional<Delivery> d = scanner.Next(0.05);
      if (!d) {
        if (stop || scanner.finished()) break;
        continue;
      }
      const double arrived = clock.Now();
      const TrackedVolume r =
          tracker.Process(d->volume, d->acquired_s, arrived, [&] { return clock.Now(); });
      if (r.published) arrivals.Add(r.sequence, arrived);
      if (o.on_tracked) o.on_tracked(r, d->volume, d->acquired_s + clock.link_offset_s());
      if (r.error.empty()) {
        ++tracked_volumes;
        const tracking::CatheterDetection& det = r.detection;
        if (det.found && det.target_found) ++target_found;
        const double past_mm = scene.TipPastSurfaceMm(d->acquired_s);
        const bool touching = past_mm >= 0.0;
        const bool reported = det.found && det.target_found && det.contact;
        contact_true += touching;
        contact_reported += reported;
        contact_true_reported += touching && reported;
        contact_reported_apart += reported && past_mm < -0.5;
      }
      if (recorder) recorder->Submit(std::move(d->volume));
      if (!r.error.empty()) log("tracker: " + r.error);
    }
  });

  // The servo thread's RUN rows go to the disk from a thread of their own (created here,
  // before the servo thread is raised to real time).
  RunRowQueue rows(writer.get());

  // However this function is left (an exception in the servo loop included), the tracker
  // thread is stopped and joined first: a joinable std::thread must not be destroyed.
  struct TrackerJoin {
    std::atomic<bool>& stop;
    DelayedScanner& scanner;
    std::thread& thread;
    ~TrackerJoin() {
      stop = true;
      scanner.Stop();
      if (thread.joinable()) thread.join();
    }
  } tracker_join{stop, scanner, tracker_thread};

  // Servo: 1 kHz on absolute deadlines, in this thread.
  std::vector<double> latency_ms;
  double em_sq = 0.0, true_sq = 0.0;
  std::uint64_t em_n = 0, true_n = 0;
  hw::SimEmTracker em(scene.em_options(), 0.0);
  const double period = catheter.servo.period_s;
  // The newest applied estimate whose arrival the tracker has not noted yet (the servo can
  // apply an estimate before the tracker thread is back from Publish): its latency is
  // taken once the arrival is known, with the time it was applied.
  std::optional<std::pair<std::uint64_t, double>> pending;  // sequence, applied_s
  double last_latency_arrived_s = -std::numeric_limits<double>::infinity();
  std::uint64_t latency_out_of_order = 0;
  // This thread becomes the servo thread; the scanner, tracker, recorder and DDS threads
  // exist already and keep their normal priority.
  ServoCycleClock cycle_clock(clock, period, &servo, o.realtime);
  for (const std::string& r : cycle_clock.realtime().refusals) log("real time: " + r);
  log("real time: " + cycle_clock.realtime().Summary());
  servo.Start(0.0);
  for (std::uint64_t k = 0;; ++k) {
    const double t = static_cast<double>(k) * period;
    if (t > o.duration_s) break;
    cycle_clock.Wait(k);
    const ServoCycle c = servo.Cycle(t, k);
    if (c.applied_sequence) pending = std::make_pair(*c.applied_sequence, clock.Now());
    if (pending) {
      if (const std::optional<double> arrived = arrivals.Find(pending->first)) {
        const double applied = pending->second;
        // latency.csv's rows go in arrival order; an estimate applied after a newer one's
        // (seen once under the sanitizers' load) is counted, not written out of order.
        if (*arrived > last_latency_arrived_s) {
          latency_ms.push_back(1e3 * (applied - *arrived));
          rows.AddLatency({*arrived, applied});
          last_latency_arrived_s = *arrived;
        } else {
          ++latency_out_of_order;
        }
        pending.reset();
      }
    }
    const double tip_true = plant.truth().tip_mm;
    scene.SetPlantTip(t, tip_true);
    const Eigen::Vector3d tip_img = scene.TipImage(tip_true);
    if (t >= o.metrics_start_s) {
      true_sq += (tip_img - scene.DesiredTip(t)).squaredNorm();
      ++true_n;
    }
    while (em.next_sample_s() <= t) {
      const double t_sample = em.next_sample_s();
      const formats::EmSample r = em.Sample(tip_img);
      if (!o.external_em) rows.AddEm(r);
      if (r.valid && t_sample >= o.metrics_start_s) {
        const double t_pipeline = r.t_s - scene.em_options().clock_offset_s;
        em_sq += (em_to_image * r.position_mm - scene.DesiredTip(t_pipeline)).squaredNorm();
        ++em_n;
      }
    }
    if (k % 10 == 0)
      rows.AddServo(t, servo.follower().mode(), c.record.reference_mm, c.record.base_mm,
                    c.record.tip_mm, static_cast<double>(servo.stats().fault_events),
                    scene.TargetImage(t), tip_img);
    if (k % 1000 == 0 && k > 0)  // once a second: a line of progress (the one allocation)
      log(Fmt("t %.0f s: mode %s, volumes %llu, detected %llu", t,
              control::ToString(servo.follower().mode()).c_str(),
              static_cast<unsigned long long>(scanner.acquired()),
              static_cast<unsigned long long>(tracker.stats().measured)));
    cycle_clock.Done();
  }
  stop = true;
  scanner.Stop();
  tracker_thread.join();
  servo.WaitStatesPublished(1.0);  // the publisher thread's last state, counted
  rows.Stop();                     // the servo's rows on disk (and flushed)
  if (!rows.error().empty())
    throw std::runtime_error("demo: writing the RUN rows: " + rows.error());
  if (rows.lost() > 0)
    log(Fmt("RUN rows: %llu row(s) lost (the row writer fell behind the servo)",
            static_cast<unsigned long long>(rows.lost())));

  const ServoNodeStats& ss = servo.stats();
  const TrackerStats& ts = tracker.stats();
  result.servo_cycles = ss.cycles;
  result.realtime = cycle_clock.realtime();
  result.timing = cycle_clock.Report();
  result.servo_overruns = result.timing.overruns;
  result.deadline_holds = ss.deadline_holds;
  result.deadline_retracts = ss.deadline_retracts;
  result.timing_json = ServoTimingJson(result.realtime, result.timing, so.watchdog,
                                       ss.deadline_holds, ss.deadline_retracts);
  if (!o.out_dir.empty())
    formats::ReplaceFileContents(o.out_dir / "timing.json", result.timing_json + "\n");
  result.limit_faults = ss.limit_interventions;
  result.limit_violations = ss.limit_violations;
  result.resumes = ss.resumes;
  result.stale_events = servo.follower().counters().stale_events;
  result.tracked_volumes = tracked_volumes;
  result.target_found = target_found;
  result.contact_true = contact_true;
  result.contact_reported = contact_reported;
  result.contact_true_reported = contact_true_reported;
  result.contact_reported_apart = contact_reported_apart;
  result.em_samples = em.samples();
  result.em_dropouts = em.dropouts();
  result.estimates_accepted = ss.estimates_accepted;
  result.rejected_link = servo.target_link_stats().validation.total_rejected();
  result.estimates_rejected = ss.estimates_rejected + result.rejected_link;
  const control::FollowerCounters& fc = servo.follower().counters();
  result.rejected_non_finite = fc.rejected_non_finite;
  result.rejected_range = fc.rejected_range;
  result.rejected_time = fc.rejected_time;
  result.rejected_confidence = fc.rejected_confidence;
  result.ekf_harmonics = tracker.ekf().harmonics();
  result.ekf_rate_hz = tracker.ekf().rate_hz();
  result.volumes = scanner.acquired();
  result.detected = ts.measured;
  result.missed_acquisitions = scanner.missed();
  result.dropped_frames = scanner.dropped() + ts.not_found + scanner.missed();
  result.tracker_errors = ts.errors;
  result.tip_to_target_rms_mm = em_n ? std::sqrt(em_sq / static_cast<double>(em_n)) : 0.0;
  result.true_tip_to_target_rms_mm =
      true_n ? std::sqrt(true_sq / static_cast<double>(true_n)) : 0.0;
  result.latency.count = latency_ms.size();
  if (latency_out_of_order > 0)
    log(Fmt("latency: %llu estimate(s) applied after a newer one, not scored",
            static_cast<unsigned long long>(latency_out_of_order)));
  if (!latency_ms.empty()) {
    result.latency.p50_ms = report::Percentile(latency_ms, 0.5);
    result.latency.p99_ms = report::Percentile(latency_ms, 0.99);
    result.latency.max_ms = report::Percentile(latency_ms, 1.0);
  }
  if (recorder) {  // what is queued is written, then synced
    recorder->Close();
    const imaging::AsyncRecorderStats rs = recorder->stats();
    result.volumes_recorded = rs.written;
    result.volumes_record_dropped = rs.dropped;
    result.record_error = rs.error;
    formats::ReplaceFileContents(o.out_dir / "volumes.json", recorder->SummaryJson());
    if (!rs.error.empty()) log("volume recording stopped: " + rs.error);
    if (rs.dropped > 0)
      log(Fmt("volume recording: %llu of %llu volumes dropped (recorder queue of %zu full)",
              static_cast<unsigned long long>(rs.dropped),
              static_cast<unsigned long long>(rs.submitted), recorder->queue_capacity()));
  }
  if (external_em.stop) external_em.stop();  // its last rows in before the flush
  if (writer) writer->Flush();
  run_guard.Keep();
  return result;
}

}  // namespace echoservo::live
