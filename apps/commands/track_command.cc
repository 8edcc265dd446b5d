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
#include "imaging/io/async_sequence_writer.h"
#include "imaging/io/recording.h"
#include "link/clock.h"
#include "live/delayed_scanner.h"
#include "live/pipeline_clock.h"
#include "live/pipeline_parameters.h"
#include "live/sim_scene.h"
#include "live/tracker_node.h"

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
  int harmonics = 8;
  int max_harmonics = 8;
  double init_window_s = 2.0;
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
  EmConnection em(a.em, "track");
  // --igtl-serve: each processed volume to the OpenIGTLink viewers (docs/slicer.md), stamped
  // with its acquisition time: --sim converts the pipeline clock with its offset to the system
  // clock (measured once at the start), --connect passes the scanner's stamp, --replay the
  // recording's.
  IgtlServe igtl(a.igtl, "track");

  live::TrackerNodeOptions to;
  to.ekf.harmonics = a.harmonics;
  to.ekf.max_harmonics = a.max_harmonics;
  to.ekf.init_window_s = a.init_window_s;
  to.follow_static_target = a.follow_static_target;
  // --set (live/pipeline_parameters.h) over the flags: every stage's parameter is accepted
  // (and recorded in run.json), the follower's and the servo's with a warning (no servo here).
  live::PipelineSettings settings = live::DefaultSettings();
  settings.tracker = to;
  {
    const std::vector<live::Assignment> sets = a.set.Parsed();
    for (const live::Assignment& s : sets) {
      const std::string& stage = live::RequireParameter(s.first).stage;
      if (stage == "follower" || stage == "servo")
        std::fprintf(stderr,
                     "track: --set %s: the %s does not run in `track` (recorded in run.json "
                     "only; `demo` and `tune` run it)\n",
                     live::FormatAssignment(s).c_str(), stage.c_str());
    }
    try {
      live::Apply(sets, settings);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("track --set: ") + e.what());
    }
    to = settings.tracker;
  }
  // A run that fails leaves no half-written RUN behind, so the same command can be retried.
  formats::RunDirGuard run_guard(a.out);
  std::unique_ptr<formats::RunWriter> writer;
  if (!a.out.empty()) {
    formats::RunInfo info;
    if (replay) {
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
    // The settings used, every parameter by name (`echoservo tune params`).
    info.meta.settings = live::AllValues(settings);
    writer = std::make_unique<formats::RunWriter>(a.out, info);
  }
  // The EM stream writes to `writer`: stopped before the writer goes, however this is left.
  struct StopEm {
    EmConnection& em;
    ~StopEm() { em.Stop(); }
  } stop_em{em};
  em.Start(writer.get());
  // The received volumes, on the recorder's thread: the tracker never waits for the disk.
  std::unique_ptr<imaging::AsyncSequenceWriter> recorder;
  if (a.save_volumes)
    recorder = std::make_unique<imaging::AsyncSequenceWriter>(fs::path(a.out) / "volumes.igs.mhd",
                                                              kRecordQueueVolumes);
  auto record = [&recorder](imaging::Volume&& v) {
    if (recorder) recorder->Submit(std::move(v));
  };
  std::unique_ptr<link::Participant> participant;
  std::unique_ptr<link::TargetPublisher> publisher;
  if (!replay) {
    participant = std::make_unique<link::Participant>(
        ToParticipantOptions(a.link, "echoservo_tracker", "tracker"));
    publisher = std::make_unique<link::TargetPublisher>(*participant);
  }
  InstallStopSignals();
  auto report_error = [&](const live::TrackedVolume& r) {
    if (!r.error.empty()) std::fprintf(stderr, "track: volume skipped: %s\n", r.error.c_str());
  };
  std::uint64_t missed = 0, dropped = 0;
  nlohmann::json ingest = nullptr;  // --connect: the OpenIGTLink client's counts
  std::optional<live::TrackerNode> node;
  std::string failure;  // --connect without a single volume: the exit status is 1

  if (replay) {
    node.emplace(to, nullptr, writer.get());
    std::unique_ptr<imaging::VolumeSource> source = imaging::OpenRecording(a.replay);
    double last = -1e300;
    while (!StopRequested()) {
      std::optional<imaging::SourceFrame> f = source->Next();
      if (!f) break;
      const double t = f->volume.timestamp_s();
      if (!(t > last)) {  // the EKF needs increasing acquisition times
        std::fprintf(stderr, "track: %s frame %lld: timestamp %.6f s does not increase; skipped\n",
                     a.replay.c_str(), static_cast<long long>(f->volume.frame_index()), t);
        ++dropped;
        continue;
      }
      last = t;
      const live::TrackedVolume r = node->Process(f->volume, t, t, [t] { return t; });
      report_error(r);
      igtl.OnTracked(r, f->volume, t);
    }
  } else if (a.sim) {
    const live::PipelineClock clock(0.2);
    to.link_offset_s = clock.link_offset_s();
    node.emplace(to, publisher.get(), writer.get());
    live::SimScene scene({a.rate_hz, a.heart_rate_bpm, a.target_p2p_mm, 8.0, a.seed});
    // The servo's tip moves the catheter in the scene.
    const double offset = clock.link_offset_s();
    link::StateSubscriber state(*participant, {},
                                [&scene, offset](const link::CatheterStateSample& s, double) {
                                  scene.SetPlantTip(s.stamp_s - offset, s.tip_estimate_mm);
                                });
    live::DelayedScanner scanner(scene, clock,
                                 {a.rate_hz, a.delay_min_s, a.delay_max_s, a.duration_s, a.seed});
    while (!StopRequested()) {
      std::optional<live::Delivery> d = scanner.Next(0.05);
      if (!d) {
        if (scanner.finished()) break;
        continue;
      }
      const double arrived = clock.Now();
      const live::TrackedVolume r =
          node->Process(d->volume, d->acquired_s, arrived, [&clock] { return clock.Now(); });
      report_error(r);
      igtl.OnTracked(r, d->volume, d->acquired_s + clock.link_offset_s());
      record(std::move(d->volume));
    }
    scanner.Stop();
    missed = scanner.missed();
    dropped = scanner.dropped();
  } else {
    node.emplace(to, publisher.get(), writer.get());
    const auto colon = a.connect.rfind(':');
    if (colon == std::string::npos)
      throw std::invalid_argument("track --connect: expected HOST:PORT, got '" + a.connect + "'");
    imaging::openigtlink::IngestOptions io;
    io.host = a.connect.substr(0, colon);
    try {
      io.port = std::stoi(a.connect.substr(colon + 1));
    } catch (const std::exception&) {
      throw std::invalid_argument("track --connect: bad port in '" + a.connect + "'");
    }
    io.queue_capacity = 2;
    io.reconnect_initial_s = kReconnectInitialS;
    io.reconnect_max_s = kReconnectMaxS;
    const std::string where = "track --connect " + a.connect;
    io.on_event = [where](const imaging::openigtlink::ConnectionEvent& e) {
      using Kind = imaging::openigtlink::ConnectionEvent::Kind;
      switch (e.kind) {
        case Kind::kConnectFailed:
          std::fprintf(stderr, "%s: %s; retrying in %.2g s (attempt %d)\n", where.c_str(),
                       e.error.c_str(), e.retry_in_s, e.attempt + 1);
          break;
        case Kind::kConnected:
          std::fprintf(stderr, "%s: connected (attempt %d)\n", where.c_str(), e.attempt);
          break;
        case Kind::kDisconnected:
          std::fprintf(stderr,
                       "%s: the scanner's connection ended after %lld volume(s): %s; "
                       "reconnecting in %.2g s\n",
                       where.c_str(), static_cast<long long>(e.frames), e.error.c_str(),
                       e.retry_in_s);
          break;
        case Kind::kGaveUp:
          break;
      }
    };
    imaging::openigtlink::IngestClient client(io);
    client.Start();
    const double start = link::NowS();
    std::uint64_t received = 0;
    bool gave_up = false;
    while (!StopRequested() && (a.duration_s <= 0 || link::NowS() - start < a.duration_s) &&
           !client.ended()) {
      if (received == 0 && a.connect_timeout_s > 0 && link::NowS() - start >= a.connect_timeout_s) {
        gave_up = true;
        break;
      }
      std::optional<imaging::openigtlink::IngestedFrame> f = client.NextFrame(0.1);
      if (!f) continue;
      ++received;
      const double acquired = f->latency_ms ? f->frame.volume.timestamp_s() : f->arrival_s;
      const live::TrackedVolume r =
          node->Process(f->frame.volume, acquired, f->arrival_s, [] { return link::NowS(); });
      report_error(r);
      igtl.OnTracked(r, f->frame.volume, acquired);
      record(std::move(f->frame.volume));
    }
    client.Stop();
    const imaging::openigtlink::IngestStats is = client.stats();
    dropped = static_cast<std::uint64_t>(is.dropped);
    ingest = {{"frames", is.frames},
              {"connections", is.connections},
              {"connect_failures", is.connect_failures},
              {"last_connect_error", is.last_connect_error},
              {"rejected", is.rejected},
              {"rejected_by_reason", is.rejected_by_reason}};
    for (const auto& [reason, n] : is.rejected_by_reason)
      std::fprintf(stderr, "track: ingest rejected %lld message(s): %s\n",
                   static_cast<long long>(n), reason.c_str());
    if (received == 0) {
      char when[96];
      if (gave_up)
        std::snprintf(when, sizeof when, "within --connect-timeout %g s", a.connect_timeout_s);
      else if (StopRequested())
        std::snprintf(when, sizeof when, "before it was stopped");
      else
        std::snprintf(when, sizeof when, "in --duration %g s", a.duration_s);
      std::string why;
      if (is.connections == 0)
        why = std::to_string(is.connect_failures) + " connection attempt(s), the last: " +
              (is.last_connect_error.empty() ? "no answer" : is.last_connect_error);
      else
        why = "connected " + std::to_string(is.connections) +
              " time(s), but no IMAGE message was accepted (" + std::to_string(is.rejected) +
              " rejected, " + std::to_string(is.skipped) + " of other types)";
      failure = where + ": no volume received " + when + " (" + why + ")" +
                (gave_up ? "; giving up" : "");
    }
  }
  const nlohmann::json em_stream = nlohmann::json::parse(em.Finish(a.out));
  const nlohmann::json igtl_serve = nlohmann::json::parse(igtl.Finish());
  if (writer) writer->Flush();
  imaging::AsyncRecorderStats rs;
  if (recorder) {  // what is queued is written, then synced
    recorder->Close();
    rs = recorder->stats();
    formats::ReplaceFileContents(fs::path(a.out) / "volumes.json", recorder->SummaryJson());
    if (!rs.error.empty())
      std::fprintf(stderr, "track: volume recording stopped: %s\n", rs.error.c_str());
    if (rs.dropped > 0)
      std::fprintf(stderr, "track: volume recording: %llu of %llu volumes dropped (queue full)\n",
                   static_cast<unsigned long long>(rs.dropped),
                   static_cast<unsigned long long>(rs.submitted));
  }

  const live::TrackerStats& s = node->stats();
  if (a.json) {
    std::cout << nlohmann::json{{"volumes", s.volumes},
                                {"measured", s.measured},
                                {"not_found", s.not_found},
                                {"errors", s.errors},
                                {"published", s.published},
                                {"publish_failures", s.publish_failures},
                                {"volumes_recorded", rs.written},
                                {"volumes_record_dropped", rs.dropped},
                                {"dropped", dropped},
                                {"missed_acquisitions", missed},
                                {"ingest", ingest},
                                {"em_stream", em_stream},
                                {"igtl_serve", igtl_serve},
                                {"ekf_harmonics", node->ekf().harmonics()},
                                {"ekf_rate_hz", node->ekf().rate_hz()},
                                {"heartbeat", HeartbeatJson(*node)},
                                {"run_dir",
                                 a.out.empty() ? nlohmann::json(nullptr) : nlohmann::json(a.out)}}
                     .dump(2)
              << "\n";
  } else {
    std::printf(
        "track: %llu volumes, %llu with catheter and target, %llu published, %llu errors; EKF %d "
        "harmonics at %.3f Hz\n",
        static_cast<unsigned long long>(s.volumes), static_cast<unsigned long long>(s.measured),
        static_cast<unsigned long long>(s.published), static_cast<unsigned long long>(s.errors),
        node->ekf().harmonics(), node->ekf().rate_hz());
    std::printf("track: %s\n", node->heartbeat().reason.c_str());
  }
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
