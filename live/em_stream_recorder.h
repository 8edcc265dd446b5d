// A run's live EM stream (`--em-connect HOST:PORT [--em-tool NAME]` of `track` and `demo`,
// apps/commands/em_connect_flags.h), a component of the tracker runtime's run: EM tracking from a
// PLUS server (imaging/igtl/em_stream.h) into the RUN's em.csv (formats::RunWriter::AddEm: the
// EM tracker's clock, s since the Unix epoch, and frame, mm), with the client's counts in
// RUN/em_stream.json and `--json`'s em_stream.
// Errors: a malformed HOST:PORT or a tool name over 20 bytes throws std::invalid_argument
// naming the flag; at run time nothing throws — connection failures, bad messages and an
// ambiguous tool are logged on stderr and counted, and the run goes on without EM data.
// Details: docs/report.md#live-em-tracking-from-plus
#pragma once

#include <filesystem>
#include <memory>
#include <string>

namespace echoservo::formats {
class RunWriter;
}
namespace echoservo::imaging::openigtlink {
class EmStreamClient;
}

namespace echoservo::live {

struct EmStreamOptions {
  std::string connect;  // HOST:PORT; empty: no live EM stream
  std::string tool;     // --em-tool; empty: the only tool streaming
};

// The live EM stream of one run. Construct it before the run starts (the flags are checked
// there), Start it with the RUN writer, Stop it before the writer goes.
class EmStreamRecorder {
 public:
  // `command` prefixes the log lines ("track", "demo"). Throws std::invalid_argument.
  EmStreamRecorder(const EmStreamOptions& flags, std::string command);
  ~EmStreamRecorder();
  EmStreamRecorder(const EmStreamRecorder&) = delete;
  EmStreamRecorder& operator=(const EmStreamRecorder&) = delete;

  bool enabled() const { return !flags_.connect.empty(); }
  // Connects in the background; each accepted sample goes to writer->AddEm (writer may be
  // null: counted only). Nothing when !enabled().
  void Start(formats::RunWriter* writer);
  void Stop();  // idempotent
  // After Stop: the counts as a JSON object text ("null" when !enabled()), also written to
  // out_dir/em_stream.json when out_dir is not empty, and a summary line on stderr.
  std::string Finish(const std::filesystem::path& out_dir);

 private:
  EmStreamOptions flags_;
  std::string command_;
  std::string host_;
  int port_ = 0;
  std::unique_ptr<imaging::openigtlink::EmStreamClient> client_;
};

}  // namespace echoservo::live
