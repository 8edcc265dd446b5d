// OpenIGTLink streaming commands (docs/openigtlink.md):
//   echoservo scanner --port N [--rate HZ] [--duration S] [--source sim|phantom]
//   echoservo ingest --connect HOST:PORT [--duration S] [--max-voxels N] [--json]
//   echoservo replay FILE|DIR [--port N] [--rate real|max] [--json]
#include <CLI/CLI.hpp>
#include <chrono>
#include <csignal>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "apps/commands/imaging_commands.h"
#include "imaging/igtl/image_message.h"
#include "imaging/igtl/image_server.h"
#include "imaging/igtl/ingest.h"
#include "imaging/igtl/phantom_source.h"
#include "imaging/io/plus_sequence.h"
#include "imaging/io/recording.h"
#include "imaging/io/truth_fields.h"
#include "imaging/sim/simulated_scanner.h"

namespace echoservo::apps {
namespace {

namespace igtl = imaging::openigtlink;

nlohmann::json LatencyJson(const igtl::LatencySummary& s) {
  return {{"count", s.count}, {"p50", s.p50_ms}, {"p99", s.p99_ms}, {"max", s.max_ms}, {"mean", s.mean_ms}};
}

nlohmann::json IngestJson(const igtl::IngestStats& s) {
  return {{"frames", s.frames},
          {"rejected", s.rejected},
          {"reasons", s.rejected_by_reason},
          {"skipped", s.skipped},
          {"skipped_types", s.skipped_by_type},
          {"dropped", s.dropped},
          {"connections", s.connections},
          {"connect_failures", s.connect_failures},
          {"bytes", s.bytes},
          {"elapsed_s", s.elapsed_s},
          {"rate_hz", s.elapsed_s > 0 ? static_cast<double>(s.frames) / s.elapsed_s : 0.0},
          {"latency_ms", LatencyJson(s.latency)},
          {"receive_ms", LatencyJson(s.receive)}};
}

nlohmann::json ServerJson(const igtl::ImageServerStats& s, int port) {
  return {{"port", port},
          {"frames_sent", s.frames_sent},
          {"messages_written", s.messages_written},
          {"bytes_written", s.bytes_written},
          {"clients_accepted", s.clients_accepted},
          {"clients_dropped", s.clients_dropped},
          {"encode_ms_mean", s.encode_ms_mean}};
}

void PrintIngestText(const igtl::IngestStats& s) {
  std::cout << "frames " << s.frames << "  rejected " << s.rejected << "  skipped " << s.skipped
            << "  dropped " << s.dropped << "  connections " << s.connections << "\n";
  for (const auto& [reason, n] : s.rejected_by_reason) std::cout << "  rejected " << reason << ": " << n << "\n";
  std::cout << "latency ms p50 " << s.latency.p50_ms << " p99 " << s.latency.p99_ms << " (" << s.latency.count
            << " frames on a shared clock); receive ms p50 " << s.receive.p50_ms << " p99 " << s.receive.p99_ms
            << "\n";
}

// Serves `source` until it ends, `duration_s` passes (> 0) or the process is interrupted.
int Serve(imaging::VolumeSource& source, igtl::ImageServerOptions options, bool json) {
  igtl::ImageServer server(source, options);
  server.Start();
  std::cerr << "serving OpenIGTLink IMAGE on " << options.bind_address << ":" << server.port() << "\n";
  server.Wait();
  const auto stats = server.stats();
  server.Stop();
  if (json) {
    std::cout << ServerJson(stats, server.port()).dump(2) << "\n";
  } else {
    std::cout << "sent " << stats.frames_sent << " frames to " << stats.clients_accepted << " client(s), "
              << stats.clients_dropped << " dropped; encode " << stats.encode_ms_mean << " ms/frame\n";
  }
  return 0;
}

// Pulls `frames` frames from `source` and writes them, with their ground truth as
// per-frame fields (imaging/io/truth_fields.h), as one compressed PLUS sequence.
void RecordFrames(imaging::VolumeSource& source, const std::string& path, std::int64_t frames, bool json) {
  std::vector<imaging::Volume> volumes;
  std::vector<std::optional<imaging::FrameGroundTruth>> truths;
  while (static_cast<std::int64_t>(volumes.size()) < frames) {
    std::optional<imaging::SourceFrame> f = source.Next();
    if (!f) break;
    volumes.push_back(std::move(f->volume));
    truths.push_back(f->truth);
  }
  imaging::PlusSequence seq = imaging::VolumesToSequence(volumes);
  for (std::size_t i = 0; i < truths.size(); ++i) {
    if (truths[i]) imaging::SetTruthFields(*truths[i], seq.frames[i].fields);
  }
  imaging::WritePlusSequence(seq, path, true);
  if (json) {
    std::cout << nlohmann::json{{"recorded", path}, {"frames", volumes.size()}}.dump(2) << "\n";
  } else {
    std::cout << "recorded " << volumes.size() << " frames with ground truth to " << path << "\n";
  }
}

void AddScanner(CLI::App& app) {
  auto* cmd = app.add_subcommand("scanner", "Serve simulated volumes as OpenIGTLink IMAGE messages");
  struct Args {
    int port = 18944;
    std::string bind = "127.0.0.1";
    double rate = -1;
    double duration = 0;
    std::int64_t frames = -1;
    std::string source = "sim";
    std::string stamps = "wall";
    int min_clients = 1;
    std::string record;
    bool json = false;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("--port", args->port, "TCP port (0: ephemeral)")->check(CLI::Range(0, 65535));
  cmd->add_option("--record", args->record,
                  "instead of serving, write --frames volumes (default 25) with their ground truth "
                  "as a PLUS sequence (.igs.mha, compressed)");
  cmd->add_option("--bind", args->bind, "IPv4 address to listen on (0.0.0.0: all)");
  cmd->add_option("--rate", args->rate, "volumes/s (default: the source's rate; 0: as fast as possible)");
  cmd->add_option("--duration", args->duration, "stop after S seconds of streaming (0: endless)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--frames", args->frames, "stop after N frames (-1: endless)");
  cmd->add_option("--source", args->source, "sim (Embree simulated scanner) or phantom (synthetic)")
      ->check(CLI::IsMember({"sim", "phantom"}));
  cmd->add_option("--timestamps", args->stamps, "wall (send time, Unix epoch) or source (acquisition time)")
      ->check(CLI::IsMember({"wall", "source"}));
  cmd->add_option("--min-clients", args->min_clients, "clients to wait for before streaming")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--json", args->json, "print the summary as JSON");
  cmd->callback([args] {
    std::unique_ptr<imaging::VolumeSource> source;
    if (args->source == "sim") {
      imaging::sim::SimulatedScannerOptions o;
      if (args->rate > 0) o.rate_hz = args->rate;
      source = std::make_unique<imaging::sim::SimulatedScanner>(o);
    } else {
      igtl::PhantomOptions o;
      if (args->rate > 0) o.rate_hz = args->rate;
      source = std::make_unique<igtl::PhantomSource>(o);
    }
    if (!args->record.empty()) {
      RecordFrames(*source, args->record, args->frames > 0 ? args->frames : 25, args->json);
      return;
    }
    igtl::ImageServerOptions so;
    so.bind_address = args->bind;
    so.port = args->port;
    if (args->rate >= 0) so.rate_hz = args->rate;
    so.max_duration_s = args->duration;
    so.max_frames = args->frames;
    so.min_clients = args->min_clients;
    so.timestamps = args->stamps == "wall" ? igtl::ImageServerOptions::Timestamps::kSendTime
                                          : igtl::ImageServerOptions::Timestamps::kSource;
    Serve(*source, so, args->json);
  });
}

void AddIngest(CLI::App& app) {
  auto* cmd = app.add_subcommand("ingest", "Receive and validate OpenIGTLink IMAGE messages; report counts and latency");
  struct Args {
    std::string connect;
    double duration = 10;
    std::int64_t max_voxels = 64LL << 20;
    std::int64_t frames = -1;
    std::size_t queue = 4;
    bool json = false;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("--connect", args->connect, "HOST:PORT of the OpenIGTLink server")->required();
  cmd->add_option("--duration", args->duration, "seconds to listen")->check(CLI::PositiveNumber);
  cmd->add_option("--frames", args->frames, "stop after N accepted frames (-1: run for --duration)");
  cmd->add_option("--max-voxels", args->max_voxels, "reject IMAGE messages with more voxels")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--queue", args->queue, "frames kept for the consumer (oldest dropped)")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--json", args->json, "print the summary as JSON");
  cmd->callback([args] {
    igtl::IngestOptions o;
    const auto colon = args->connect.rfind(':');
    if (colon == std::string::npos) throw CLI::ValidationError("--connect", "expected HOST:PORT");
    o.host = args->connect.substr(0, colon);
    try {
      o.port = std::stoi(args->connect.substr(colon + 1));
    } catch (const std::exception&) {
      throw CLI::ValidationError("--connect", "bad port in '" + args->connect + "'");
    }
    o.queue_capacity = args->queue;
    o.limits.max_voxels = args->max_voxels;
    o.limits.max_body_bytes = static_cast<std::uint64_t>(args->max_voxels) + 4096;
    igtl::IngestClient client(o);
    client.Start();
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(args->duration);
    std::int64_t consumed = 0;
    while (std::chrono::steady_clock::now() < end && !client.ended()) {
      const double left = std::chrono::duration<double>(end - std::chrono::steady_clock::now()).count();
      if (client.NextFrame(std::min(0.2, std::max(0.0, left)))) ++consumed;
      if (args->frames >= 0 && client.stats().frames >= args->frames) break;
    }
    client.Stop();
    const auto s = client.stats();
    if (args->json) {
      auto j = IngestJson(s);
      j["consumed"] = consumed;
      std::cout << j.dump(2) << "\n";
    } else {
      PrintIngestText(s);
    }
  });
}

void AddReplay(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "replay", "Play recorded volumes through the OpenIGTLink ingest path, or serve them with --port");
  struct Args {
    std::string path;
    int port = -1;
    std::string bind = "127.0.0.1";
    std::string rate = "real";
    bool json = false;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("path", args->path, "volume file, PLUS sequence or folder of volumes")->required();
  cmd->add_option("--port", args->port, "serve over OpenIGTLink on this port instead of ingesting locally")
      ->check(CLI::Range(0, 65535));
  cmd->add_option("--bind", args->bind, "IPv4 address to listen on with --port");
  cmd->add_option("--rate", args->rate, "real (recorded rate) or max")->check(CLI::IsMember({"real", "max"}));
  cmd->add_flag("--json", args->json, "print the summary as JSON");
  cmd->callback([args] {
    std::unique_ptr<imaging::VolumeSource> source = imaging::OpenRecording(args->path);
    if (args->port >= 0) {
      igtl::ImageServerOptions so;
      so.bind_address = args->bind;
      so.port = args->port;
      if (args->rate == "max") so.rate_hz = 0.0;  // real: the recording's nominal rate
      Serve(*source, so, args->json);
      return;
    }
    // Local: every frame goes through the same encode -> validate -> decode path as a
    // network frame, paced at the recorded rate unless --rate max.
    const double rate = args->rate == "real" ? source->nominal_rate_hz() : 0.0;
    const auto start = std::chrono::steady_clock::now();
    std::int64_t frames = 0, rejected = 0;
    std::map<std::string, std::int64_t> reasons;
    std::vector<double> decode_ms;
    std::vector<std::uint8_t> buffer;
    while (auto frame = source->Next()) {
      if (rate > 0) {
        std::this_thread::sleep_until(start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                  std::chrono::duration<double>(static_cast<double>(frames) / rate)));
      }
      try {
        igtl::EncodeImage(frame->volume, {}, buffer);
        const auto t0 = std::chrono::steady_clock::now();
        igtl::DecodeMessage(buffer, igtl::DecodeLimits{});
        decode_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        ++frames;
      } catch (const igtl::MessageError& e) {
        ++rejected;
        ++reasons[e.reason()];
      } catch (const std::invalid_argument& e) {  // not encodable (e.g. a dim > 65535)
        ++rejected;
        ++reasons["not_encodable"];
      }
    }
    const auto d = igtl::Summarize(decode_ms);
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (args->json) {
      std::cout << nlohmann::json{{"frames", frames},
                                  {"rejected", rejected},
                                  {"reasons", reasons},
                                  {"dropped", 0},
                                  {"elapsed_s", elapsed},
                                  {"decode_ms", LatencyJson(d)}}
                       .dump(2)
                << "\n";
    } else {
      std::cout << "replayed " << frames << " frames (" << rejected << " rejected) in " << elapsed
                << " s; decode ms p50 " << d.p50_ms << " p99 " << d.p99_ms << "\n";
    }
  });
}

}  // namespace

void AddStreamCommands(CLI::App& app) {
  AddScanner(app);
  AddIngest(app);
  AddReplay(app);
}

}  // namespace echoservo::apps
