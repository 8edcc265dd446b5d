// An OpenIGTLink scanner stream as a tracker source (live/tracker_source.h): the ingest
// client (imaging/igtl/ingest.h) connects in the background, reports every failed attempt
// and lost connection through `log` (address, errno text), retries with back-off (0.25 s
// doubling to 4 s), and the source gives up when no volume came within connect_timeout_s.
// When it ends without a single volume, failure() says why (attempts and the last error, or
// what was rejected): `track` exits with status 1 on it.
// Clock: the system clock (s since the Unix epoch). A volume's stamp is the message's
// timestamp when the scanner shares the clock (the ingest client measured a latency), else
// its arrival. Errors: std::invalid_argument for a malformed HOST:PORT.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "live/tracker_source.h"

namespace echoservo::imaging::openigtlink {
class IngestClient;
struct IngestStats;
}  // namespace echoservo::imaging::openigtlink

namespace echoservo::live {

struct IgtlSourceOptions {
  std::string address;              // HOST:PORT
  double duration_s = 0.0;          // stop after this long (0: until the stream ends)
  double connect_timeout_s = 10.0;  // give up when no volume came by then (0: never)
  double reconnect_initial_s = 0.25, reconnect_max_s = 4.0;
  std::string where;  // prefixes log lines and the failure, e.g. "track --connect HOST:PORT"
  std::function<void(const std::string&)> log;  // connection events; may be null
};

class IgtlSource : public TrackerSource {
 public:
  // Connects in the background at once. Throws std::invalid_argument for a bad address.
  explicit IgtlSource(IgtlSourceOptions options);
  ~IgtlSource() override;
  std::optional<SourceVolume> Next(double timeout_s) override;
  bool finished() const override { return finished_; }
  double Now() const override;
  void Stop() override;
  SourceCounts counts() const override;
  // The client's counts (frames, connections, rejections by reason); after the run.
  imaging::openigtlink::IngestStats ingest_stats() const;
  // Non-empty when the run ended without a volume: why, e.g. "track --connect h:p: no volume
  // received within --connect-timeout 10 s (3 connection attempt(s), the last: Connection
  // refused); giving up".
  std::string failure() const;

 private:
  IgtlSourceOptions o_;
  std::unique_ptr<imaging::openigtlink::IngestClient> client_;
  double start_s_ = 0.0;
  std::uint64_t received_ = 0;
  bool finished_ = false, gave_up_ = false, stopped_ = false;
};

}  // namespace echoservo::live
