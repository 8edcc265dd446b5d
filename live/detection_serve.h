// A run's detection server (`--igtl-serve PORT [--igtl-volumes] [--igtl-bind ADDR]` of `track`
// and `demo`, apps/commands/igtl_serve_flags.h), a sink of the tracker runtime: the
// tracker's detections served over OpenIGTLink to viewers such as 3D Slicer
// (imaging/igtl/detection_server.h): per processed volume a TRANSFORM `CatheterToImage`, a
// POINT `Detections` (tip, target), a STATUS when the catheter is lost, and with
// --igtl-volumes the IMAGE `Image`, all in RAS, stamped with the acquisition time (s since
// the Unix epoch). The tracker's call (OnTracked) only hands the values over; the server's own
// thread encodes and writes. `--json` gains an `igtl_serve` object with the server's counts.
// Clocks: `demo` and `track --sim` acquire on the pipeline clock (s since the run's start);
// the caller converts with the pipeline clock's offset to the system clock, measured once at
// the start (live/pipeline_clock.h), so stamps do not drift within a run.
// Errors: a port outside [0, 65535], --igtl-volumes or --igtl-bind without --igtl-serve throw
// std::invalid_argument naming the flag; a port that cannot be bound throws
// std::runtime_error before the run starts. Details: docs/slicer.md, docs/live.md.
#pragma once

#include <memory>
#include <string>

namespace echoservo::imaging {
class Volume;
namespace openigtlink {
class DetectionServer;
}
}  // namespace echoservo::imaging

namespace echoservo::live {

struct TrackedVolume;

struct DetectionServeOptions {
  int port = -1;  // --igtl-serve; < 0: no server
  bool volumes = false;
  std::string bind;  // --igtl-bind; empty: 127.0.0.1
};

// The detection server of one run (nothing when the flags do not ask for one).
class DetectionServe {
 public:
  // Checks the flags, binds and starts serving (a log line on stderr names the port).
  // `command` prefixes the log lines. Throws std::invalid_argument, std::runtime_error.
  DetectionServe(const DetectionServeOptions& flags, const std::string& command);
  ~DetectionServe();
  DetectionServe(const DetectionServe&) = delete;
  DetectionServe& operator=(const DetectionServe&) = delete;

  bool enabled() const { return server_ != nullptr; }
  int port() const;
  // One processed volume, acquired at `acquired_unix_s` (s since the Unix epoch). Never
  // blocks on a client; a volume that could not be processed counts as not found.
  void OnTracked(const TrackedVolume& result, const imaging::Volume& volume,
                 double acquired_unix_s);
  // Closes every connection (idempotent); then the counts as a JSON object text ("null"
  // when not enabled) and, unless `quiet`, a summary line on stderr.
  std::string Finish(bool quiet = false);

 private:
  std::string command_;
  std::unique_ptr<imaging::openigtlink::DetectionServer> server_;
};

}  // namespace echoservo::live
