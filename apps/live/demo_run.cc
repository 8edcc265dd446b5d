#include "apps/live/demo_run.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

#include "control/servo_loop.h"
#include "control/target_follower.h"
#include "control/track_experiment.h"
#include "control/trajectory.h"
#include "estimation/accuracy_report.h"
#include "estimation/heartbeat_ekf.h"
#include "hw/run_record.h"
#include "hw/seed_plant.h"
#include "hw/sim_em_tracker.h"
#include "hw/simulated_catheter.h"
#include "imaging/sim/catheter_scene.h"
#include "imaging/sim/simulated_scanner.h"
#include "link/clock.h"
#include "link/dds_link.h"
#include "tracking/radon_detector.h"

namespace echoservo::live {
namespace {

using Clock = std::chrono::steady_clock;

// The scanner's catheter advance at the plant's tip position 0: the tip then rests
// 10.5 mm short of the annulus's near face (5.5–15.5 mm as it moves ±5 mm), and following
// it at a 5 mm standoff keeps the plant's tip within 0–11 mm of travel.
constexpr double kAdvanceAtZeroMm = 3.0;

// A delivered volume, waiting for the tracker.
struct Delivery {
  imaging::Volume volume;
  double acquired_s;
  double deliver_s;
};

// Arrival times of the published volumes by sequence number: the latency's start, which
// the DDS sample does not carry (in-process bookkeeping of the demo only).
struct Arrivals {
  std::mutex m;
  std::deque<std::pair<std::uint64_t, double>> seq_arrived;
  void Add(std::uint64_t seq, double arrived_s) {
    std::lock_guard lock(m);
    seq_arrived.emplace_back(seq, arrived_s);
    while (seq_arrived.size() > 256) seq_arrived.pop_front();
  }
  std::optional<double> Find(std::uint64_t seq) {
    std::lock_guard lock(m);
    for (const auto& [s, a] : seq_arrived)
      if (s == seq) return a;
    return std::nullopt;
  }
};

std::string Fmt(const char* f, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

// The 3 × 4 rows of a rigid transform, comma-separated (run.json "em_to_image").
std::string RowMajor(const Eigen::Isometry3d& t) {
  std::string out;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) {
      if (!out.empty()) out += ',';
      out += Fmt("%.9g", t.matrix()(r, c));
    }
  return out;
}

}  // namespace

void DemoOptions::Validate() const {
  auto bad = [](const std::string& f, const std::string& why) {
    throw std::invalid_argument("demo: " + f + " " + why);
  };
  if (!(duration_s > 0 && duration_s <= 3600)) bad("--duration", "must be in (0, 3600] s");
  if (!(rate_hz > 0 && rate_hz <= 60)) bad("--rate", "must be in (0, 60] vol/s");
  if (!(delay_min_s >= 0 && delay_max_s >= delay_min_s && delay_max_s <= 1)) bad("--delay", "must satisfy 0 ≤ min ≤ max ≤ 1 s");
  if (!(heart_rate_bpm >= 30 && heart_rate_bpm <= 180)) bad("--heart-rate", "must be in [30, 180] bpm");
  if (!(target_p2p_mm > 0 && target_p2p_mm <= 20)) bad("--target-p2p", "must be in (0, 20] mm");
  if (!(standoff_mm >= 0 && standoff_mm <= 30)) bad("--standoff", "must be in [0, 30] mm");
  if (!(metrics_start_s >= 0 && metrics_start_s < duration_s)) bad("--metrics-start", "must be in [0, duration)");
  if (!(dds_domain >= 0 && dds_domain <= 232)) bad("--dds-domain", "must be in [0, 232]");
  if (!(guidewire_od_mm > 0 && sheath_id_mm > guidewire_od_mm && sheath_id_mm <= 5))
    bad("--sheath-id/--guidewire-od", "must satisfy 0 < guidewire < sheath ≤ 5 mm");
}

DemoResult RunDemo(const DemoOptions& o) {
  o.Validate();
  auto log = [&](const std::string& s) {
    if (o.log) o.log(s);
  };

  // The scene: the default water-tank catheter pose, the annulus moving along its normal
  // with the mitral trajectory, the catheter advanced to the plant's tip.
  imaging::sim::SimulatedScannerOptions so;
  imaging::sim::PlaceCatheterScene({0.0, 10.0, 60.0, 0.0, kAdvanceAtZeroMm}, so);
  so.rate_hz = o.rate_hz;
  so.seed = o.seed;
  const std::unique_ptr<control::Trajectory> target_motion =
      control::MakeTrajectory(Fmt("mitral:%g:%g", o.heart_rate_bpm, o.target_p2p_mm));
  std::atomic<double> plant_tip_mm{0.0};
  const imaging::sim::CatheterPose rest_pose = so.catheter_pose;
  so.catheter_pose_at = [&](double) {
    imaging::sim::CatheterPose p = rest_pose;
    p.advance_mm = rest_pose.advance_mm + plant_tip_mm.load();
    return p;
  };
  so.target_displacement_mm = [&](double t) { return target_motion->Evaluate(t).position_mm; };
  imaging::sim::SimulatedScanner scanner(so);

  // Ground truth in the image frame as functions of time (the plant's tip, the displaced
  // annulus), for the figures and truth.csv.
  const auto& cg = so.catheter_geometry;
  const Eigen::Isometry3d base = rest_pose.base_to_world;
  auto tip_image = [&](double tip_mm) {
    return scanner.WorldToImage(base * Eigen::Vector3d(0, 0, rest_pose.advance_mm + tip_mm + cg.sheath_length_mm + cg.wire_protrusion_mm));
  };
  const Eigen::Vector3d axis_image =
      (scanner.WorldToImage(base * Eigen::Vector3d(0, 0, 1)) - scanner.WorldToImage(base * Eigen::Vector3d::Zero())).normalized();
  const Eigen::Vector3d displacement_image =
      scanner.WorldToImage(so.annulus_to_world.linear().col(2)) - scanner.WorldToImage(Eigen::Vector3d::Zero());
  const auto first = scanner.Render(0.0);
  if (!first.truth || !first.truth->target_visible) throw std::logic_error("demo: the scene's target is not visible");
  const Eigen::Vector3d target0 = first.truth->target_mm;
  const double d0 = target_motion->Evaluate(0.0).position_mm;
  auto target_image = [&](double t) { return Eigen::Vector3d(target0 + (target_motion->Evaluate(t).position_mm - d0) * displacement_image); };
  auto desired_tip = [&](double t) { return Eigen::Vector3d(target_image(t) - o.standoff_mm * axis_image); };

  // The EM tracker: its own frame and clock.
  hw::SimEmTrackerOptions eo;
  eo.image_to_em = Eigen::Translation3d(120.0, -35.0, 210.0) * Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized());
  eo.clock_offset_s = 0.0375;
  eo.seed = o.seed + 11;
  const Eigen::Isometry3d em_to_image = eo.image_to_em.inverse();

  // The RUN directory (hw/run_record.h): run.json now, the streams as they come.
  std::unique_ptr<hw::RunWriter> writer;
  if (!o.out_dir.empty()) {
    hw::RunInfo info;
    info.heart_rate_hz = o.heart_rate_bpm / 60.0;
    info.standoff_mm = o.standoff_mm;
    info.metadata_json = Fmt("{\"source\": \"echoservo demo\", \"seed\": %llu, \"duration_s\": %.3f, \"em_to_image\": \"%s\"}",
                             static_cast<unsigned long long>(o.seed), o.duration_s, RowMajor(em_to_image).c_str());
    writer = std::make_unique<hw::RunWriter>(o.out_dir, info);
  }

  DemoResult result;
  std::atomic<bool> stop{false};
  std::mutex queue_m;
  std::condition_variable queue_cv;
  std::deque<Delivery> queue;
  Arrivals arrivals;
  std::atomic<std::uint64_t> dropped{0}, detected{0}, volumes{0}, missed{0}, tracker_errors{0}, publish_failures{0};
  const Clock::time_point start = Clock::now() + std::chrono::milliseconds(50);
  auto now_s = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };
  auto at = [&](double t_s) { return start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(t_s)); };
  // The DDS link (link/dds_link.h): the tracker's and the servo's participants, loopback
  // only. Samples carry the shared (system) clock: pipeline time + system_offset_s.
  const double system_offset_s = link::NowS() - now_s();
  link::ParticipantOptions po;
  po.domain_id = o.dds_domain;
  po.loopback_only = true;
  po.name = "echoservo_demo_tracker";
  link::Participant tracker_participant(po);
  po.name = "echoservo_demo_servo";
  link::Participant servo_participant(po);
  link::TargetPublisher target_pub(tracker_participant);
  link::TargetSubscriber target_sub(servo_participant);
  target_pub.WaitForSubscribers(1, 5.0);

  // Scanner: acquire at k / rate, render on one TBB thread, queue for delivery after the delay.
  std::thread scanner_thread([&] {
    tbb::task_arena one(1);
    std::mt19937_64 rng(o.seed + 3);
    std::uniform_real_distribution<double> delay(o.delay_min_s, o.delay_max_s);
    double last_deliver = 0.0;
    for (std::int64_t k = 0; !stop; ++k) {
      double t_acq = static_cast<double>(k) / o.rate_hz;
      // A scanner acquires on its own schedule: slots missed while rendering are lost.
      if (now_s() > t_acq + 1.0 / o.rate_hz) {
        const auto behind = static_cast<std::int64_t>(std::floor(now_s() * o.rate_hz)) - k;
        missed += static_cast<std::uint64_t>(std::max<std::int64_t>(0, behind));
        k += std::max<std::int64_t>(0, behind);
        t_acq = static_cast<double>(k) / o.rate_hz;
      }
      if (t_acq > o.duration_s) break;
      std::this_thread::sleep_until(at(t_acq));
      std::optional<imaging::SourceFrame> frame;
      one.execute([&] { frame = scanner.Render(t_acq); });
      ++volumes;
      last_deliver = std::max(last_deliver, t_acq + delay(rng));
      {
        std::lock_guard lock(queue_m);
        queue.push_back({std::move(frame->volume), t_acq, last_deliver});
      }
      queue_cv.notify_one();
    }
  });

  // Tracker: detect, update the EKF with the target's axis coordinate, publish the motion.
  std::thread tracker_thread([&] {
    tracking::RadonDetector detector;
    estimation::HeartbeatEkfOptions ekf_options;
    ekf_options.init_window_s = 2.0;
    ekf_options.max_harmonics = 8;
    estimation::HeartbeatEkf ekf(ekf_options);
    std::optional<tracking::Line3> reference;  // the axis coordinates' direction (origin: the image's)
    std::uint64_t sequence = 0;
    while (true) {
      std::optional<Delivery> next;
      {
        std::unique_lock lock(queue_m);
        queue_cv.wait_for(lock, std::chrono::milliseconds(50), [&] { return !queue.empty() || stop; });
        if (queue.empty()) {
          if (stop) break;
          continue;
        }
        // Only the newest delivered volume matters: older ones still queued (the tracker fell
        // behind) are dropped.
        while (queue.size() > 1 && queue[1].deliver_s <= now_s()) {
          queue.pop_front();
          ++dropped;
        }
        next.emplace(std::move(queue.front()));
        queue.pop_front();
      }
      const Delivery& d = *next;
      std::this_thread::sleep_until(at(d.deliver_s));
      const double arrived = now_s();
      tracking::CatheterDetection det;
      try {
        det = detector.Track(d.volume);
      } catch (const std::exception& e) {
        ++tracker_errors;
        log(std::string("tracker: ") + e.what());
        continue;
      }
      const bool ok = det.found && det.target_found;
      if (!ok) {
        ++dropped;
        if (writer) writer->AddTarget({d.acquired_s, arrived, now_s(), false, {}, {}, {}, det.confidence});
        continue;
      }
      ++detected;
      if (!reference) reference = det.axis;
      // Axis coordinates s = p · axis (the link's convention: origin at the image origin).
      const double s_target = det.target_mm.dot(reference->direction);
      try {
        ekf.Process(d.acquired_s, s_target);
      } catch (const std::exception& e) {  // a bad measurement never stops the tracker
        ++tracker_errors;
        log(std::string("tracker: ") + e.what());
        continue;
      }
      const double published = now_s();
      if (ekf.initialised()) {
        link::TargetEstimateSample sample;
        sample.sequence_number = ++sequence;
        sample.acquisition_time_s = d.acquired_s + system_offset_s;
        sample.publication_time_s = published + system_offset_s;
        sample.target_mm = det.target_mm;
        sample.axis = reference->direction;
        sample.tip_mm = det.tip_mm;
        sample.motion = ekf.Motion();
        sample.motion.t0_s += system_offset_s;
        sample.motion.valid_until_s += system_offset_s;
        sample.confidence = det.confidence;
        arrivals.Add(sample.sequence_number, arrived);
        if (!target_pub.Publish(sample)) ++publish_failures;
      }
      if (writer)
        writer->AddTarget({d.acquired_s, arrived, published, true, det.target_mm, det.tip_mm, det.axis.direction,
                           det.confidence});
    }
    result.ekf_harmonics = ekf.harmonics();
    result.ekf_rate_hz = ekf.rate_hz();
  });

  // Servo: 1 kHz on absolute deadlines.
  std::vector<double> latency_ms;
  double em_sq = 0.0, true_sq = 0.0;
  std::uint64_t em_n = 0, true_n = 0;
  {
    // The seed's water-tank catheter: a 1.50 mm guidewire in a 1.59 mm sheath, its two bends.
    hw::CatheterConfig catheter = hw::SeedTrackingCatheter();
    catheter.sheath_id_mm = o.sheath_id_mm;
    catheter.guidewire_od_mm = o.guidewire_od_mm;
    hw::PlantOptions plant_options = hw::SeedCalibratedPlant(catheter, o.seed);
    hw::SimulatedCatheter plant(plant_options);
    plant.ResetTo(0.0);
    plant.Configure();
    plant.Activate();
    control::ServoLoop loop(plant, control::SeedServoConfig(plant_options, true));
    loop.Start(0.0);
    // The static inverse: the adaptive one learned poorly from a reference that changes with
    // every volume (servo tracking 1.2 mm RMS against 0.19 mm with the static inverse).
    control::StaticInverse compensator(plant_options.config.TotalBendRad() * plant_options.config.GapMm(),
                                       loop.config().limits.max_acceleration_mm_s2);
    control::FollowerConfig fc;
    fc.standoff_mm = o.standoff_mm;
    fc.offset_gain = 0.05;
    control::TargetFollower follower(fc);
    hw::SimEmTracker em(eo, 0.0);
    const std::size_t tip_index = plant.StateIndex(hw::iface::kTipPosition);
    link::TargetEstimateSample sample;
    bool enabled = false;
    const double period = 1e-3;
    for (std::uint64_t k = 0;; ++k) {
      const double t = static_cast<double>(k) * period;
      if (t > o.duration_s) break;
      std::this_thread::sleep_until(at(t));
      if (now_s() > t + period) ++result.servo_overruns;
      std::optional<double> pending_arrival;
      if (target_sub.TryTakeLatest(sample)) {
        {
          control::TargetEstimateInput in;
          in.acquired_s = sample.acquisition_time_s - system_offset_s;
          in.published_s = sample.publication_time_s - system_offset_s;
          in.target_motion = sample.motion;
          in.target_motion.t0_s -= system_offset_s;
          in.target_motion.valid_until_s -= system_offset_s;
          in.tip_axis_mm = sample.tip_mm.dot(sample.axis);
          in.confidence = sample.confidence;
          if (follower.Accept(in, t)) {
            // The operator's enable: once tracking delivers, and again after a retraction
            // (the demo resumes by itself; a clinical system would wait for the operator).
            if (!enabled || follower.mode() == control::FollowerMode::kRetracting) {
              if (enabled) ++result.resumes;
              follower.Enable(t);
              enabled = true;
            }
            pending_arrival = arrivals.Find(sample.sequence_number);
          }
        }
      }
      follower.Update(t, plant.state(tip_index));
      const control::CycleRecord rec = loop.Cycle(t, k, follower, compensator);
      ++result.servo_cycles;
      if (pending_arrival) {
        const double applied = now_s();
        latency_ms.push_back(1e3 * (applied - *pending_arrival));
        if (writer) writer->AddLatency({*pending_arrival, applied});
      }
      const double tip_true = plant.truth().tip_mm;
      plant_tip_mm.store(tip_true);
      const Eigen::Vector3d tip_img = tip_image(tip_true);
      if (t >= o.metrics_start_s) {
        true_sq += (tip_img - desired_tip(t)).squaredNorm();
        ++true_n;
      }
      while (em.next_sample_s() <= t) {
        const double t_sample = em.next_sample_s();
        const hw::EmSample r = em.Sample(tip_img);
        if (writer) writer->AddEm(r);
        if (r.valid && t_sample >= o.metrics_start_s) {
          const double t_pipeline = r.t_s - eo.clock_offset_s;
          em_sq += (em_to_image * r.position_mm - desired_tip(t_pipeline)).squaredNorm();
          ++em_n;
        }
      }
      if (k % 10 == 0 && writer) {
        writer->AddServo({t, control::ToString(follower.mode()), rec.reference_mm, rec.base_mm, rec.tip_mm,
                          static_cast<double>(follower.faults())});
        writer->AddTruth({t, target_image(t), tip_img});
      }
      if (k % 1000 == 0 && k > 0)
        log(Fmt("t %.0f s: mode %s, volumes %llu, detected %llu", t, control::ToString(follower.mode()).c_str(),
                static_cast<unsigned long long>(volumes.load()), static_cast<unsigned long long>(detected.load())));
    }
    result.limit_faults = loop.limiter().faults();
    result.em_samples = em.samples();
    result.em_dropouts = em.dropouts();
    const auto& c = follower.counters();
    result.estimates_accepted = c.accepted;
    const link::SubscriberStats ls = target_sub.stats();
    result.estimates_rejected = c.rejected_non_finite + c.rejected_range + c.rejected_time + c.rejected_confidence +
                                ls.validation.total_rejected();
  }
  stop = true;
  queue_cv.notify_all();
  scanner_thread.join();
  tracker_thread.join();

  result.volumes = volumes;
  result.detected = detected;
  result.dropped_frames = dropped + missed;
  result.missed_acquisitions = missed;
  result.tracker_errors = tracker_errors;
  result.tip_to_target_rms_mm = em_n ? std::sqrt(em_sq / static_cast<double>(em_n)) : 0.0;
  result.true_tip_to_target_rms_mm = true_n ? std::sqrt(true_sq / static_cast<double>(true_n)) : 0.0;
  result.latency.count = latency_ms.size();
  if (!latency_ms.empty()) {
    result.latency.p50_ms = estimation::Percentile(latency_ms, 0.5);
    result.latency.p99_ms = estimation::Percentile(latency_ms, 0.99);
    result.latency.max_ms = estimation::Percentile(latency_ms, 1.0);
  }
  if (writer) writer->Flush();
  return result;
}

}  // namespace echoservo::live
