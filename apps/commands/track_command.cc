// `echoservo track`: the tracker process — volumes in, catheter and target detected, the
// heartbeat EKF's predicted target motion published over DDS (live::TrackerNode).
// Sources:
//   --connect HOST:PORT  an OpenIGTLink scanner stream (imaging/igtl/ingest.h); the
//                        acquisition time is the message's timestamp when it is on the
//                        shared clock (the scanner stamps wall-clock time), else arrival;
//   --sim                the embedded simulated scanner (water tank, 50–100 ms imaging
//                        delay); its catheter is advanced to the tip the servo reports on
//                        the catheter-state topic, which closes the loop across processes;
//   --replay FILE        a recording (PLUS sequence, volume file or folder; imaging/io/
//                        recording.h) processed as fast as possible on its own timestamps,
//                        offline (nothing published): with --out, a RUN directory whose
//                        targets a report scores against the recorded run's EM log.
// --out RUN writes targets.csv (and run.json; for a replay of RUN/volumes.igs.mhd the
// recorded run's heart rate, standoff and EM calibration are carried over); with
// --save-volumes (live sources) also the received volumes, on a recorder thread through a
// bounded queue (RUN/volumes.igs.mhd; imaging/io/async_sequence_writer.h).
// --connect reports every failed attempt and lost connection on stderr (address, errno
// text), retries with back-off (0.25 s doubling to 4 s), gives up when no volume came
// within --connect-timeout S, and exits with status 1 when it never received a volume.
// --em-connect HOST:PORT [--em-tool NAME] records a PLUS server's EM stream into RUN/em.csv
// (apps/commands/em_connect_flags.h); --json's em_stream has its counts.
// --igtl-serve PORT [--igtl-volumes] [--igtl-bind ADDR] serves each processed volume's
// detection to OpenIGTLink viewers such as 3D Slicer (apps/commands/igtl_serve_flags.h,
// docs/slicer.md); --json's igtl_serve has the server's counts.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>

#include "apps/commands/em_connect_flags.h"
#include "apps/commands/igtl_serve_flags.h"
#include "apps/commands/link_flags.h"
#include "apps/commands/live_commands.h"
#include "apps/commands/set_flags.h"
#include "formats/durable_file.h"
#include "formats/run_dir_guard.h"
#include "formats/run_record.h"
#include "imaging/igtl/ingest.h"
#include "live/igtl_source.h"
#include "live/pipeline_clock.h"
#include "live/pipeline_parameters.h"
#include "live/sim_scene.h"
#include "live/tracker_node.h"
#include "live/tracker_runtime.h"
#include "live/tracker_source.h"

namespace echoservo::apps {
namespace {

// The heartbeat significance test at the end of the run (live/tracker_node.h): whether the
// EKF's heartbeat was being published, and why (not); rate null without one.
nlohmann::json HeartbeatJson(const live::TrackerNode& node) {
  const estimation::HeartbeatEvidence& e = node.heartbeat();
  return {{"significant", e.significant},
          {"reason", e.reason},
          {"rate_hz", e.significant ? nlohmann::json(e.rate_hz) : nlohmann::json(nullptr)},
          {"confidence", e.confidence()},
          {"peak_snr", e.peak_snr},
          {"snr_threshold", e.snr_threshold},
          {"repeat_snr", e.repeat_snr},
          {"p2p_mm", e.p2p_mm},
          {"noise_mm", e.noise_mm},
          {"published_heartbeat", node.stats().published_heartbeat},
          {"published_hold", node.stats().published_hold}};
}

namespace fs = std::filesystem;

// --connect: the wait before reconnecting, doubling after each failed attempt.
constexpr double kReconnectInitialS = 0.25;
constexpr double kReconnectMaxS = 4.0;
// --save-volumes: volumes waiting for the disk before one is dropped (4.9 MB each).
constexpr std::size_t kRecordQueueVolumes = 16;

struct TrackArgs {
  LinkFlags link;
  EmConnectFlags em;    // --em-connect: a PLUS server's EM stream into RUN/em.csv
  IgtlServeFlags igtl;  // --igtl-serve: the detections to OpenIGTLink viewers (Slicer)
  SetFlags set;         // --set NAME=VALUE: tunable parameters, over the flags below
  bool sim = false;
  std::string connect;
  std::string replay;
  double duration_s = 0.0;
  double connect_timeout_s = 10.0;  // --connect: give up when no volume came by then (0: never)
  std::string out;
  bool save_volumes = false;
  bool json = false;
  bool follow_static_target = false;  // TrackerNodeOptions::follow_static_target
  // EKF
  int harmonics = live::TrackerNodeOptions::DefaultEkfOptions().harmonics;
  int max_harmonics = live::TrackerNodeOptions::DefaultEkfOptions().max_harmonics;
  double init_window_s = live::TrackerNodeOptions::DefaultEkfOptions().init_window_s;
  // --sim
  double rate_hz = 25.0, delay_min_s = 0.05, delay_max_s = 0.10, heart_rate_bpm = 60.0,
         target_p2p_mm = 10.0;
  std::uint64_t seed = 1;
};

// run.json of the replayed recording's RUN directory, when the file lies in one.
formats::RunInfo ReplayInfo(const fs::path& file) {
  formats::RunInfo info;
  info.meta.source = "echoservo track --replay";
  info.meta.replay_of = file.string();
  info.meta.time_base = formats::RunTimeBase::kRecording;
  const fs::path dir = file.parent_path().empty() ? fs::path(".") : file.parent_path();
  if (fs::exists(dir / "run.json")) {
    const formats::RunRecord recorded = formats::ReadRunRecord(dir);
    info.heart_rate_hz = recorded.info.heart_rate_hz;
    info.standoff_mm = recorded.info.standoff_mm;
    info.meta.em_to_image = recorded.info.meta.em_to_image;
    if (recorded.info.meta.time_base != formats::RunTimeBase::kUnstated)
      info.meta.time_base = recorded.info.meta.time_base;
    info.meta.pipeline_to_unix_s = recorded.info.meta.pipeline_to_unix_s;
  }
  return info;
}

// The run's source: exactly one of --sim, --connect, --replay (checked by RunTrack).
struct TrackSource {
  std::optional<live::PipelineClock> clock;  // --sim
  std::optional<live::SimScene> scene;       // --sim
  std::unique_ptr<link::StateSubscriber> state;
  std::unique_ptr<live::TrackerSource> source;
  live::IgtlSource* igtl = nullptr;  // --connect
};

// Fills `s` in place: the scanner holds references to its clock and scene.
void OpenTrackSource(const TrackArgs& a, link::Participant* participant, TrackSource& s) {
  auto log = [](const std::string& line) { std::fprintf(stderr, "track: %s\n", line.c_str()); };
  if (!a.replay.empty()) {
    s.source = std::make_unique<live::ReplaySource>(a.replay, log);
  } else if (a.sim) {
    s.clock.emplace(0.2);
    s.scene.emplace(
        live::SimSceneOptions{a.rate_hz, a.heart_rate_bpm, a.target_p2p_mm, 8.0, a.seed});
    // The servo's tip moves the catheter in the scene.
    const double offset = s.clock->link_offset_s();
    live::SimScene* scene = &*s.scene;
    s.state = std::make_unique<link::StateSubscriber>(
        *participant, link::ValidationLimits{},
        [scene, offset](const link::CatheterStateSample& st, double) {
          scene->SetPlantTip(st.stamp_s - offset, st.tip_estimate_mm);
        });
    s.source = std::make_unique<live::SimScannerSource>(
        *s.scene, *s.clock,
        live::DelayedScannerOptions{a.rate_hz, a.delay_min_s, a.delay_max_s, a.duration_s, a.seed});
  } else {
    live::IgtlSourceOptions io;
    io.address = a.connect;
    io.duration_s = a.duration_s;
    io.connect_timeout_s = a.connect_timeout_s;
    io.reconnect_initial_s = kReconnectInitialS;
    io.reconnect_max_s = kReconnectMaxS;
    io.where = "track --connect " + a.connect;
    io.log = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
    auto igtl = std::make_unique<live::IgtlSource>(io);
    s.igtl = igtl.get();
    s.source = std::move(igtl);
  }
}

// --connect: the OpenIGTLink client's counts, each rejection reason on stderr.
nlohmann::json IngestJson(const live::IgtlSource& source) {
  const imaging::openigtlink::IngestStats is = source.ingest_stats();
  for (const auto& [reason, n] : is.rejected_by_reason)
    std::fprintf(stderr, "track: ingest rejected %lld message(s): %s\n", static_cast<long long>(n),
                 reason.c_str());
  return {{"frames", is.frames},
          {"connections", is.connections},
          {"connect_failures", is.connect_failures},
          {"last_connect_error", is.last_connect_error},
          {"rejected", is.rejected},
          {"rejected_by_reason", is.rejected_by_reason}};
}

// run.json of the run: the replayed recording's calibration and clock, or this run's.
formats::RunInfo TrackRunInfo(const TrackArgs& a, const live::PipelineSettings& settings) {
  formats::RunInfo info;
  if (!a.replay.empty()) {
    info = ReplayInfo(a.replay);
  } else {
    info.heart_rate_hz = a.sim ? std::optional<double>(a.heart_rate_bpm / 60.0) : std::nullopt;
    // The clock of the run's times (docs/report.md#the-run-directory): --sim's pipeline
    // clock (s since the run's start), or --connect's system clock (s since the Unix epoch:
    // the scanner's stamps on a shared clock, else the arrival times).
    info.meta.source = a.sim ? "echoservo track --sim" : "echoservo track --connect";
    info.meta.time_base = a.sim ? formats::RunTimeBase::kPipeline : formats::RunTimeBase::kUnix;
    if (a.sim) info.meta.seed = a.seed;
  }
  info.meta.settings = live::AllValues(settings);  // every parameter by name
  return info;
}

void PrintTrackSummary(const TrackArgs& a, const live::TrackerRuntime& runtime,
                       const live::TrackerRunResult& r, const nlohmann::json& ingest,
                       const nlohmann::json& em_stream, const nlohmann::json& igtl_serve) {
  const live::TrackerNode& node = runtime.node();
  const live::TrackerStats& s = r.stats;
  if (!a.json) {
    std::printf(
        "track: %llu volumes, %llu with catheter and target, %llu published, %llu errors; EKF %d "
        "harmonics at %.3f Hz\n",
        static_cast<unsigned long long>(s.volumes), static_cast<unsigned long long>(s.measured),
        static_cast<unsigned long long>(s.published), static_cast<unsigned long long>(s.errors),
        node.ekf().harmonics(), node.ekf().rate_hz());
    std::printf("track: %s\n", node.heartbeat().reason.c_str());
    return;
  }
  std::cout << nlohmann::json{{"volumes", s.volumes},
                              {"measured", s.measured},
                              {"not_found", s.not_found},
                              {"errors", s.errors},
                              {"published", s.published},
                              {"publish_failures", s.publish_failures},
                              {"volumes_recorded", r.recorder.written},
                              {"volumes_record_dropped", r.recorder.dropped},
                              {"dropped", r.source.dropped + r.source.skipped},
                              {"missed_acquisitions", r.source.missed},
                              {"ingest", ingest},
                              {"em_stream", em_stream},
                              {"igtl_serve", igtl_serve},
                              {"ekf_harmonics", node.ekf().harmonics()},
                              {"ekf_rate_hz", node.ekf().rate_hz()},
                              {"heartbeat", HeartbeatJson(node)},
                              {"run_dir",
                               a.out.empty() ? nlohmann::json(nullptr) : nlohmann::json(a.out)}}
                   .dump(2)
            << "\n";
}

void RunTrack(const TrackArgs& a) {
  const int sources = (a.sim ? 1 : 0) + (a.connect.empty() ? 0 : 1) + (a.replay.empty() ? 0 : 1);
  if (sources != 1)
    throw std::invalid_argument(
        "track: give exactly one of --sim, --connect HOST:PORT, --replay FILE");
  if (a.sim && a.duration_s <= 0)
    throw std::invalid_argument("track --sim: --duration S is required");
  const bool replay = !a.replay.empty();
  if (a.save_volumes && a.out.empty())
    throw std::invalid_argument("track --save-volumes: needs --out RUN");
  if (a.save_volumes && replay)
    throw std::invalid_argument("track --save-volumes: a replay is recorded already");
  if (!a.em.connect.empty() && replay)
    throw std::invalid_argument("track --em-connect: a replay is offline (use its RUN's em.csv)");
  live::EmStreamRecorder em(a.em, "track");
  // --igtl-serve: each processed volume to the OpenIGTLink viewers (docs/slicer.md), stamped
  // with its acquisition time on the system clock.
  IgtlServe igtl(a.igtl, "track");
  // The flags, then --set (live/pipeline_parameters.h) for the stages `track` runs.
  live::PipelineSettings settings = live::DefaultSettings();
  settings.tracker.ekf.harmonics = a.harmonics;
  settings.tracker.ekf.max_harmonics = a.max_harmonics;
  settings.tracker.ekf.init_window_s = a.init_window_s;
  settings.tracker.follow_static_target = a.follow_static_target;
  live::ApplyFor("track", live::kTrackerStages, a.set.Parsed(), settings);
  // A run that fails leaves no half-written RUN behind, so the same command can be retried.
  formats::RunDirGuard run_guard(a.out);
  std::unique_ptr<formats::RunWriter> writer;
  if (!a.out.empty())
    writer = std::make_unique<formats::RunWriter>(a.out, TrackRunInfo(a, settings));
  // The EM stream writes to `writer`: stopped before the writer goes, however this is left.
  struct StopEm {
    live::EmStreamRecorder& em;
    ~StopEm() { em.Stop(); }
  } stop_em{em};
  em.Start(writer.get());
  std::unique_ptr<link::Participant> participant;
  std::unique_ptr<link::TargetPublisher> publisher;
  if (!replay) {
    participant = std::make_unique<link::Participant>(
        ToParticipantOptions(a.link, "echoservo_tracker", "tracker"));
    publisher = std::make_unique<link::TargetPublisher>(*participant);
  }
  TrackSource src;
  OpenTrackSource(a, participant.get(), src);
  InstallStopSignals();
  live::TrackerRuntimeOptions ro;
  ro.node = settings.tracker;
  ro.node.link_offset_s = src.source->unix_offset_s();
  ro.publisher = publisher.get();
  ro.writer = writer.get();
  if (a.save_volumes) ro.record_to = fs::path(a.out) / "volumes.igs.mhd";
  ro.record_queue_volumes = kRecordQueueVolumes;
  ro.log = [](const std::string& line) { std::fprintf(stderr, "track: %s\n", line.c_str()); };
  ro.stop = [] { return StopRequested(); };
  const double unix_offset_s = src.source->unix_offset_s();
  ro.on_tracked = [&igtl, unix_offset_s](const live::TrackedVolume& r, const live::SourceVolume& v,
                                         double) {
    igtl.OnTracked(r, v.volume, v.stamp_s + unix_offset_s);
  };
  live::TrackerRuntime runtime(ro);
  const live::TrackerRunResult result = runtime.Run(*src.source);
  const nlohmann::json ingest = src.igtl ? IngestJson(*src.igtl) : nlohmann::json(nullptr);
  const std::string failure = src.igtl ? src.igtl->failure() : "";
  const nlohmann::json em_stream = nlohmann::json::parse(em.Finish(a.out));
  const nlohmann::json igtl_serve = nlohmann::json::parse(igtl.Finish());
  if (writer) writer->Flush();
  PrintTrackSummary(a, runtime, result, ingest, em_stream, igtl_serve);
  if (!failure.empty()) throw std::runtime_error(failure);
  run_guard.Keep();
}

}  // namespace

void AddTrackCommand(CLI::App& app) {
  auto a = std::make_shared<TrackArgs>();
  CLI::App* cmd = app.add_subcommand(
      "track", "tracker process: volumes → detector → heartbeat EKF → target estimates over DDS");
  cmd->add_flag("--sim", a->sim,
                "the embedded simulated scanner, its catheter moved by the servo's reported tip");
  cmd->add_option("--connect", a->connect, "HOST:PORT of an OpenIGTLink scanner stream");
  cmd->add_option("--replay", a->replay,
                  "a recording (PLUS sequence, volume file or folder), processed offline");
  cmd->add_option("--duration", a->duration_s, "run length, s (0: until the stream ends or SIGINT)")
      ->check(CLI::Range(0.0, 86400.0));
  cmd->add_option("--connect-timeout", a->connect_timeout_s,
                  "--connect: give up (exit status 1) when no volume arrived within S s; 0: "
                  "keep trying")
      ->check(CLI::Range(0.0, 86400.0));
  cmd->add_option("--out", a->out, "write a RUN directory (targets.csv, run.json)");
  cmd->add_flag("--save-volumes", a->save_volumes,
                "--sim/--connect: also record the received volumes to RUN/volumes.igs.mhd (+ "
                ".raw) on a recorder thread (a full queue drops, counted), for --replay");
  cmd->add_option("--harmonics", a->harmonics, "EKF harmonics (0: automatic)")
      ->check(CLI::Range(0, 12));
  cmd->add_option("--max-harmonics", a->max_harmonics, "EKF automatic harmonics up to")
      ->check(CLI::Range(1, 12));
  cmd->add_flag("--follow-static-target", a->follow_static_target,
                "without a significant heartbeat, publish the hold at the detector's confidence "
                "(a static phantom the servo should follow) instead of at confidence 0");
  cmd->add_option("--init-window", a->init_window_s, "EKF initial window, s")
      ->check(CLI::Range(1.0, 30.0));
  cmd->add_option("--rate", a->rate_hz, "--sim: volume rate, vol/s")->check(CLI::Range(1.0, 60.0));
  cmd->add_option("--delay-min", a->delay_min_s, "--sim: imaging delay, lower end, s")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--delay-max", a->delay_max_s, "--sim: imaging delay, upper end, s")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--heart-rate", a->heart_rate_bpm, "--sim: target heart rate, bpm")
      ->check(CLI::Range(30.0, 180.0));
  cmd->add_option("--target-p2p", a->target_p2p_mm, "--sim: target excursion, mm")
      ->check(CLI::Range(0.1, 20.0));
  cmd->add_option("--seed", a->seed, "--sim: simulation seed");
  AddLinkFlags(*cmd, a->link);
  AddEmConnectFlags(*cmd, a->em);
  AddIgtlServeFlags(*cmd, a->igtl);
  AddSetFlags(*cmd, a->set);
  cmd->add_flag("--json", a->json, "print the summary as JSON");
  cmd->callback([a] { RunTrack(*a); });
}

}  // namespace echoservo::apps
