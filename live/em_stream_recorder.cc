#include "live/em_stream_recorder.h"

#include <cstdio>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "formats/durable_file.h"
#include "formats/run_record.h"
#include "imaging/igtl/em_stream.h"
#include "imaging/igtl/tcp.h"

namespace echoservo::live {

namespace igtl = imaging::openigtlink;

EmStreamRecorder::EmStreamRecorder(const EmStreamOptions& flags, std::string command)
    : flags_(flags), command_(std::move(command)) {
  if (!flags_.tool.empty() && flags_.connect.empty())
    throw std::invalid_argument(command_ + " --em-tool: needs --em-connect HOST:PORT");
  if (!enabled()) return;
  try {
    igtl::tcp::SplitHostPort(flags_.connect, host_, port_);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(command_ + " --em-connect: " + e.what());
  }
  if (port_ < 1 || port_ > 65535)
    throw std::invalid_argument(command_ + " --em-connect: port " + std::to_string(port_) +
                                " is not in 1..65535");
  if (flags_.tool.size() > 20)
    throw std::invalid_argument(command_ + " --em-tool: '" + flags_.tool +
                                "' is longer than OpenIGTLink's 20-byte names");
}

EmStreamRecorder::~EmStreamRecorder() { Stop(); }

void EmStreamRecorder::Start(formats::RunWriter* writer) {
  if (!enabled() || client_) return;
  igtl::EmStreamOptions o;
  o.host = host_;
  o.port = port_;
  o.tool = flags_.tool;
  o.reconnect_initial_s = 0.05;
  o.reconnect_max_s = 2.0;
  o.on_sample = [writer](const igtl::EmStreamSample& s) {
    if (writer) writer->AddEm({s.t_s, s.position_mm, s.valid});
  };
  const std::string where = command_ + " --em-connect " + flags_.connect;
  o.on_event = [where](const igtl::ConnectionEvent& e) {
    using Kind = igtl::ConnectionEvent::Kind;
    switch (e.kind) {
      case Kind::kConnectFailed:
        // The first failure and then every tenth: a tracker that is not up yet is normal.
        if (e.attempt == 1 || e.attempt % 10 == 0)
          std::fprintf(stderr, "%s: %s; retrying (attempt %d), the run goes on without EM\n",
                       where.c_str(), e.error.c_str(), e.attempt + 1);
        break;
      case Kind::kConnected:
        std::fprintf(stderr, "%s: connected\n", where.c_str());
        break;
      case Kind::kDisconnected:
        std::fprintf(
            stderr, "%s: the EM stream ended after %lld sample(s): %s; reconnecting in %.2g s\n",
            where.c_str(), static_cast<long long>(e.frames), e.error.c_str(), e.retry_in_s);
        break;
      case Kind::kGaveUp:
        break;
    }
  };
  client_ = std::make_unique<igtl::EmStreamClient>(std::move(o));
  client_->Start();
}

void EmStreamRecorder::Stop() {
  if (client_) client_->Stop();
}

std::string EmStreamRecorder::Finish(const std::filesystem::path& out_dir) {
  if (!enabled()) return "null";
  Stop();
  const igtl::EmStreamStats s = client_ ? client_->stats() : igtl::EmStreamStats{};
  nlohmann::json j = {{"address", flags_.connect},
                      {"tool", s.tool},
                      {"tool_error", s.tool_error},
                      {"connections", s.connections},
                      {"connect_failures", s.connect_failures},
                      {"disconnects", s.disconnects},
                      {"reconnects", s.reconnects},
                      {"messages", s.messages},
                      {"samples", s.samples},
                      {"valid_samples", s.valid_samples},
                      {"dropouts_by_reason", s.dropouts_by_reason},
                      {"duplicates_skipped", s.duplicates_skipped},
                      {"older_skipped", s.older_skipped},
                      {"rejected", s.rejected},
                      {"rejected_by_reason", s.rejected_by_reason},
                      {"rejected_by_device", s.rejected_by_device},
                      {"skipped_by_type", s.skipped_by_type},
                      {"status_by_code", s.status_by_code},
                      {"tools_seen", s.tools_seen},
                      {"first_t_s", s.samples ? nlohmann::json(s.first_t_s) : nullptr},
                      {"last_t_s", s.samples ? nlohmann::json(s.last_t_s) : nullptr},
                      {"last_error", s.last_error},
                      {"bytes", s.bytes}};
  const std::string text = j.dump(2);
  if (!out_dir.empty()) formats::ReplaceFileContents(out_dir / "em_stream.json", text + "\n");
  std::fprintf(stderr,
               "%s --em-connect %s: %lld sample(s) of '%s' (%lld valid), %lld duplicate(s) and "
               "%lld older skipped, %lld rejected, %lld connection(s), %lld disconnect(s)\n",
               command_.c_str(), flags_.connect.c_str(), static_cast<long long>(s.samples),
               s.tool.c_str(), static_cast<long long>(s.valid_samples),
               static_cast<long long>(s.duplicates_skipped),
               static_cast<long long>(s.older_skipped), static_cast<long long>(s.rejected),
               static_cast<long long>(s.connections), static_cast<long long>(s.disconnects));
  for (const auto& [what, n] : s.rejected_by_device)
    std::fprintf(stderr, "%s --em-connect: rejected %lld message(s): %s\n", command_.c_str(),
                 static_cast<long long>(n), what.c_str());
  if (!s.tool_error.empty())
    std::fprintf(stderr, "%s --em-connect: %s\n", command_.c_str(), s.tool_error.c_str());
  if (s.samples > 0 && s.valid_samples == 0)
    std::fprintf(stderr, "%s --em-connect: all %lld sample(s) of '%s' were invalid (drop-outs)\n",
                 command_.c_str(), static_cast<long long>(s.samples), s.tool.c_str());
  return text;
}

}  // namespace echoservo::live
