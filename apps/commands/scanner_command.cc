// `echoservo scanner --port N [--rate HZ] [--duration S] [--source sim|phantom]`, or
// `--record FILE`: the simulated scanner served over OpenIGTLink or recorded with ground
// truth (docs/openigtlink.md).
#include <CLI/CLI.hpp>
#include <chrono>
#include <csignal>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "apps/commands/imaging_commands.h"
#include "apps/commands/openigtlink_output.h"
#include "imaging/igtl/image_message.h"
#include "imaging/igtl/image_server.h"
#include "imaging/igtl/ingest.h"
#include "imaging/igtl/phantom_source.h"
#include "imaging/io/plus_sequence.h"
#include "imaging/io/recording.h"
#include "imaging/io/truth_fields.h"
#include "imaging/sim/simulated_scanner.h"

namespace echoservo::apps {

namespace igtl = imaging::openigtlink;

namespace {

// Pulls `frames` frames from `source` and writes them, with their ground truth as
// per-frame fields (imaging/io/truth_fields.h), as one compressed PLUS sequence.
void RecordFrames(imaging::VolumeSource& source, const std::string& path, std::int64_t frames,
                  bool json) {
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

}  // namespace

void AddScannerCommand(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("scanner", "Serve simulated volumes as OpenIGTLink IMAGE messages");
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
  cmd->add_option("--rate", args->rate,
                  "volumes/s (default: the source's rate; 0: as fast as possible)");
  cmd->add_option("--duration", args->duration, "stop after S seconds of streaming (0: endless)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--frames", args->frames, "stop after N frames (-1: endless)");
  cmd->add_option("--source", args->source, "sim (Embree simulated scanner) or phantom (synthetic)")
      ->check(CLI::IsMember({"sim", "phantom"}));
  cmd->add_option("--timestamps", args->stamps,
                  "wall (send time, Unix epoch) or source (acquisition time)")
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

}  // namespace echoservo::apps
