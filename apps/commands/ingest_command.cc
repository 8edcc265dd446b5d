// `echoservo ingest --connect HOST:PORT [--duration S] [--max-voxels N] [--json]`: receive and
// validate an OpenIGTLink IMAGE stream (docs/openigtlink.md).
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

void AddIngestCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "ingest", "Receive and validate OpenIGTLink IMAGE messages; report counts and latency");
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
  cmd->add_option("--frames", args->frames,
                  "stop after N accepted frames (-1: run for --duration)");
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
    const auto end =
        std::chrono::steady_clock::now() + std::chrono::duration<double>(args->duration);
    std::int64_t consumed = 0;
    while (std::chrono::steady_clock::now() < end && !client.ended()) {
      const double left =
          std::chrono::duration<double>(end - std::chrono::steady_clock::now()).count();
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

}  // namespace echoservo::apps
