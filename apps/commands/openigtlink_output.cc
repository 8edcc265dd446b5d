// Output shared by the OpenIGTLink commands (scanner, ingest, replay): JSON and text of
// ingest and server counts, and serving a volume source until it ends.
#include "apps/commands/openigtlink_output.h"

#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "imaging/igtl/image_server.h"
#include "imaging/igtl/ingest.h"
#include "imaging/volume_source.h"

namespace echoservo::apps {

namespace igtl = imaging::openigtlink;

nlohmann::json LatencyJson(const igtl::LatencySummary& s) {
  return {{"count", s.count},
          {"p50", s.p50_ms},
          {"p99", s.p99_ms},
          {"max", s.max_ms},
          {"mean", s.mean_ms}};
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

namespace {

nlohmann::json ServerJson(const igtl::ImageServerStats& s, int port) {
  return {{"port", port},
          {"frames_sent", s.frames_sent},
          {"messages_written", s.messages_written},
          {"bytes_written", s.bytes_written},
          {"clients_accepted", s.clients_accepted},
          {"clients_disconnected", s.clients_disconnected},
          {"clients_stalled", s.clients_stalled},
          {"frames_unsent", s.frames_unsent},
          {"encode_ms_mean", s.encode_ms_mean}};
}

}  // namespace

void PrintIngestText(const igtl::IngestStats& s) {
  std::cout << "frames " << s.frames << "  rejected " << s.rejected << "  skipped " << s.skipped
            << "  dropped " << s.dropped << "  connections " << s.connections << "\n";
  for (const auto& [reason, n] : s.rejected_by_reason)
    std::cout << "  rejected " << reason << ": " << n << "\n";
  std::cout << "latency ms p50 " << s.latency.p50_ms << " p99 " << s.latency.p99_ms << " ("
            << s.latency.count << " frames on a shared clock); receive ms p50 " << s.receive.p50_ms
            << " p99 " << s.receive.p99_ms << "\n";
}

// Serves `source` until it ends, `duration_s` passes (> 0) or the process is interrupted.
int Serve(imaging::VolumeSource& source, igtl::ImageServerOptions options, bool json) {
  igtl::ImageServer server(source, options);
  server.Start();
  std::cerr << "serving OpenIGTLink IMAGE on " << options.bind_address << ":" << server.port()
            << "\n";
  server.Wait();
  const auto stats = server.stats();
  server.Stop();
  if (json) {
    std::cout << ServerJson(stats, server.port()).dump(2) << "\n";
  } else {
    auto count = [](std::int64_t n, const char* one, const char* many) {
      return std::to_string(n) + " " + (n == 1 ? one : many);
    };
    std::cout << "sent " << count(stats.frames_sent, "frame", "frames") << " to "
              << count(stats.clients_accepted, "client", "clients") << "; "
              << count(stats.clients_disconnected, "client", "clients") << " disconnected, "
              << count(stats.clients_stalled, "client", "clients") << " cut off for stalling; "
              << count(stats.frames_unsent, "frame", "frames") << " reached no client; encode "
              << stats.encode_ms_mean << " ms/frame\n";
  }
  return 0;
}

}  // namespace echoservo::apps
