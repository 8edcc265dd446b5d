// `echoservo replay FILE|DIR [--port N] [--rate real|max] [--json]`: recorded volumes through
// the OpenIGTLink ingest path, or served with --port (docs/openigtlink.md).
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

void AddReplayCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "replay",
      "Play recorded volumes through the OpenIGTLink ingest path, or serve them with --port");
  struct Args {
    std::string path;
    int port = -1;
    std::string bind = "127.0.0.1";
    std::string rate = "real";
    bool json = false;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("path", args->path, "volume file, PLUS sequence or folder of volumes")
      ->required();
  cmd->add_option("--port", args->port,
                  "serve over OpenIGTLink on this port instead of ingesting locally")
      ->check(CLI::Range(0, 65535));
  cmd->add_option("--bind", args->bind, "IPv4 address to listen on with --port");
  cmd->add_option("--rate", args->rate, "real (recorded rate) or max")
      ->check(CLI::IsMember({"real", "max"}));
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
        std::this_thread::sleep_until(
            start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                        std::chrono::duration<double>(static_cast<double>(frames) / rate)));
      }
      try {
        igtl::EncodeImage(frame->volume, {}, buffer);
        const auto t0 = std::chrono::steady_clock::now();
        igtl::DecodeMessage(buffer, igtl::DecodeLimits{});
        decode_ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
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
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (args->json) {
      std::cout << nlohmann::json{{"frames", frames},     {"rejected", rejected},
                                  {"reasons", reasons},   {"dropped", 0},
                                  {"elapsed_s", elapsed}, {"decode_ms", LatencyJson(d)}}
                       .dump(2)
                << "\n";
    } else {
      std::cout << "replayed " << frames << " frames (" << rejected << " rejected) in " << elapsed
                << " s; decode ms p50 " << d.p50_ms << " p99 " << d.p99_ms << "\n";
    }
  });
}

}  // namespace echoservo::apps
