// Output shared by the OpenIGTLink commands `scanner`, `ingest` and `replay`
// (docs/openigtlink.md): ingest counts and latencies (ms) as JSON or text, and serving a
// volume source as IMAGE messages until it ends, its duration passes or SIGINT.
#pragma once

#include <nlohmann/json_fwd.hpp>

namespace echoservo::imaging {
class VolumeSource;
}
namespace echoservo::imaging::openigtlink {
struct LatencySummary;
struct IngestStats;
struct ImageServerOptions;
}  // namespace echoservo::imaging::openigtlink

namespace echoservo::apps {

nlohmann::json LatencyJson(const imaging::openigtlink::LatencySummary& s);
nlohmann::json IngestJson(const imaging::openigtlink::IngestStats& s);
void PrintIngestText(const imaging::openigtlink::IngestStats& s);
// Serves `source`; prints the server's counts (JSON with `json`). Returns 0.
int Serve(imaging::VolumeSource& source, imaging::openigtlink::ImageServerOptions options,
          bool json);

}  // namespace echoservo::apps
