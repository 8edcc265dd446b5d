#include "live/igtl_source.h"

#include <cstdio>
#include <stdexcept>
#include <utility>

#include "imaging/igtl/ingest.h"
#include "link/clock.h"

namespace echoservo::live {
namespace {

std::string IgtlFmt(const char* f, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

}  // namespace

IgtlSource::IgtlSource(IgtlSourceOptions options) : o_(std::move(options)) {
  const auto colon = o_.address.rfind(':');
  if (colon == std::string::npos)
    throw std::invalid_argument(o_.where + ": expected HOST:PORT, got '" + o_.address + "'");
  imaging::openigtlink::IngestOptions io;
  io.host = o_.address.substr(0, colon);
  try {
    std::size_t used = 0;
    io.port = std::stoi(o_.address.substr(colon + 1), &used);
    if (used != o_.address.size() - colon - 1) throw std::invalid_argument("trailing text");
  } catch (const std::exception&) {
    throw std::invalid_argument(o_.where + ": bad port in '" + o_.address + "'");
  }
  io.queue_capacity = 2;
  io.reconnect_initial_s = o_.reconnect_initial_s;
  io.reconnect_max_s = o_.reconnect_max_s;
  io.on_event = [where = o_.where, log = o_.log](const imaging::openigtlink::ConnectionEvent& e) {
    if (!log) return;
    using Kind = imaging::openigtlink::ConnectionEvent::Kind;
    switch (e.kind) {
      case Kind::kConnectFailed:
        log(IgtlFmt("%s: %s; retrying in %.2g s (attempt %d)", where.c_str(), e.error.c_str(),
                    e.retry_in_s, e.attempt + 1));
        break;
      case Kind::kConnected:
        log(IgtlFmt("%s: connected (attempt %d)", where.c_str(), e.attempt));
        break;
      case Kind::kDisconnected:
        log(IgtlFmt(
            "%s: the scanner's connection ended after %lld volume(s): %s; reconnecting "
            "in %.2g s",
            where.c_str(), static_cast<long long>(e.frames), e.error.c_str(), e.retry_in_s));
        break;
      case Kind::kGaveUp:
        break;
    }
  };
  client_ = std::make_unique<imaging::openigtlink::IngestClient>(io);
  client_->Start();
  start_s_ = link::NowS();
}

IgtlSource::~IgtlSource() { Stop(); }

double IgtlSource::Now() const { return link::NowS(); }

void IgtlSource::Stop() {
  if (stopped_) return;
  stopped_ = true;
  finished_ = true;
  client_->Stop();
}

std::optional<SourceVolume> IgtlSource::Next(double timeout_s) {
  if (finished_) return std::nullopt;
  const double elapsed = link::NowS() - start_s_;
  if ((o_.duration_s > 0 && elapsed >= o_.duration_s) || client_->ended()) {
    Stop();
    return std::nullopt;
  }
  if (received_ == 0 && o_.connect_timeout_s > 0 && elapsed >= o_.connect_timeout_s) {
    gave_up_ = true;
    Stop();
    return std::nullopt;
  }
  std::optional<imaging::openigtlink::IngestedFrame> f = client_->NextFrame(timeout_s);
  if (!f) return std::nullopt;
  const double stamp_s = f->latency_ms ? f->frame.volume.timestamp_s() : f->arrival_s;
  return SourceVolume{std::move(f->frame.volume), stamp_s, f->arrival_s, received_++, std::nullopt};
}

SourceCounts IgtlSource::counts() const {
  const imaging::openigtlink::IngestStats s = client_->stats();
  SourceCounts c;
  c.acquired = static_cast<std::uint64_t>(s.frames);
  c.dropped = static_cast<std::uint64_t>(s.dropped);
  return c;
}

imaging::openigtlink::IngestStats IgtlSource::ingest_stats() const { return client_->stats(); }

std::string IgtlSource::failure() const {
  if (received_ > 0 || !finished_) return "";
  const imaging::openigtlink::IngestStats is = client_->stats();
  std::string when;
  if (gave_up_)
    when = IgtlFmt("within --connect-timeout %g s", o_.connect_timeout_s);
  else if (o_.duration_s > 0 && link::NowS() - start_s_ >= o_.duration_s)
    when = IgtlFmt("in --duration %g s", o_.duration_s);
  else
    when = "before it was stopped";
  std::string why;
  if (is.connections == 0)
    why = std::to_string(is.connect_failures) + " connection attempt(s), the last: " +
          (is.last_connect_error.empty() ? "no answer" : is.last_connect_error);
  else
    why = "connected " + std::to_string(is.connections) +
          " time(s), but no IMAGE message was accepted (" + std::to_string(is.rejected) +
          " rejected, " + std::to_string(is.skipped) + " of other types)";
  return o_.where + ": no volume received " + when + " (" + why + ")" +
         (gave_up_ ? "; giving up" : "");
}

}  // namespace echoservo::live
