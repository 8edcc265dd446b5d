#include "imaging/igtl/em_stream.h"

#include <algorithm>
#include <stdexcept>
#include <vector>

#include "imaging/igtl/client_connection.h"

namespace echoservo::imaging::openigtlink {
namespace {

constexpr std::size_t kEmMaxToolNameBytes = 20;

// PLUS on a version-1 link marks an invalid tool by sending the identity (vtkPlusIgtlMessage-
// Common::GetIgtlMatrix leaves it when the tool's status is not OK): an exact identity in
// float32, which a real sensor pose never is.
bool EmIsExactIdentity(const Eigen::Isometry3d& t) {
  return t.matrix() == Eigen::Matrix4d::Identity();
}

std::string EmStatusOf(const std::vector<std::pair<std::string, std::string>>& metadata,
                       const std::string& key) {
  for (const auto& [k, v] : metadata) {
    if (k == key) return v;
  }
  return "";
}

}  // namespace

EmStreamClient::EmStreamClient(EmStreamOptions options) : options_(std::move(options)) {}

EmStreamClient::~EmStreamClient() { Stop(); }

void EmStreamClient::Start() {
  if (options_.port < 1 || options_.port > 65535) {
    throw std::invalid_argument("EM stream: port " + std::to_string(options_.port) +
                                " is not in 1..65535");
  }
  if (options_.tool.size() > kEmMaxToolNameBytes) {
    throw std::invalid_argument("EM stream: tool name '" + options_.tool +
                                "' is longer than OpenIGTLink's 20-byte device names");
  }
  if (!(options_.reconnect_initial_s > 0) ||
      options_.reconnect_max_s < options_.reconnect_initial_s) {
    throw std::invalid_argument("EM stream: need 0 < reconnect_initial_s <= reconnect_max_s");
  }
  if (!options_.on_sample) throw std::invalid_argument("EM stream: on_sample is required");
  stats_.tool = options_.tool;
  thread_ = std::thread([this] { Run(); });
}

void EmStreamClient::Stop() {
  stop_ = true;
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

EmStreamStats EmStreamClient::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

void EmStreamClient::Reject(const std::string& reason, const std::string& device) {
  std::lock_guard lock(mutex_);
  ++stats_.rejected;
  ++stats_.rejected_by_reason[reason];
  ++stats_.rejected_by_device[reason + " " + (device.empty() ? "(no name)" : device)];
}

void EmStreamClient::Run() {
  ReconnectHooks hooks;
  hooks.connect_failed = [this](const std::string& error) {
    std::lock_guard lock(mutex_);
    ++stats_.connect_failures;
    stats_.last_error = error;
  };
  hooks.connected = [this] {
    std::lock_guard lock(mutex_);
    if (stats_.connections > 0) ++stats_.reconnects;
    ++stats_.connections;
  };
  hooks.session = [this](int fd) { return Session(fd); };
  hooks.progress = [this] {
    std::lock_guard lock(mutex_);
    return stats_.messages;
  };
  hooks.disconnected = [this](const std::string& why) {
    std::lock_guard lock(mutex_);
    ++stats_.disconnects;
    stats_.last_error = why;
  };
  hooks.frames = [this] {
    std::lock_guard lock(mutex_);
    return stats_.samples;
  };
  if (options_.on_event) {  // called in place, not copied: its state stays the caller's
    hooks.on_event = [this](const ConnectionEvent& e) { options_.on_event(e); };
  }
  hooks.wait = [this](double s) { WaitUnlessStopped(mutex_, cv_, stop_, s); };
  RunReconnectLoop({options_.host, options_.port, options_.connect_timeout_ms,
                    options_.reconnect_initial_s, options_.reconnect_max_s, -1},
                   stop_, hooks);
}

std::string EmStreamClient::Session(int fd) {
  std::string device;  // of the message being read
  // Reads poll so that Stop() is honoured (client_connection.h); a failed one is counted
  // against `device` and ends the session (reader.why() says why).
  SessionReader reader(
      fd, stop_, options_.stall_timeout_ms,
      [this](std::size_t n) {
        std::lock_guard lock(mutex_);
        stats_.bytes += static_cast<std::int64_t>(n);
      },
      [&](const std::string& reason) { Reject(reason, device); });
  const DecodeLimits framing;  // 64 MiB + 4 KiB: the most any message may announce
  std::vector<std::uint8_t> body;
  body.reserve(options_.max_tracking_body_bytes);
  std::vector<std::uint8_t> scratch(64 << 10);
  while (!stop_) {
    std::uint8_t header_bytes[kHeaderBytes];
    device.clear();
    if (!reader.Read(header_bytes, kHeaderBytes, false)) return reader.why();
    MessageHeader header;
    try {
      header = ParseHeader(header_bytes, framing);
    } catch (const MessageError& e) {
      Reject(e.reason(), "");  // the framing can no longer be trusted: reconnect
      return std::string("bad message header (") + e.what() + ")";
    }
    device = header.device_name;
    const bool tracking =
        header.type == "TRANSFORM" || header.type == "TDATA" || header.type == "STATUS";
    if (!tracking || header.body_size > options_.max_tracking_body_bytes) {
      // Read past it without keeping it: the stream stays in step.
      std::uint64_t left = header.body_size;
      while (left > 0) {
        const auto chunk = static_cast<std::size_t>(std::min<std::uint64_t>(left, scratch.size()));
        if (!reader.Read(scratch.data(), chunk, true)) return reader.why();
        left -= chunk;
      }
      if (tracking) {
        Reject("body_too_large", device);
      } else {
        std::lock_guard lock(mutex_);
        ++stats_.messages;
        ++stats_.skipped_by_type[header.type];
      }
      continue;
    }
    body.resize(static_cast<std::size_t>(header.body_size));
    if (!reader.Read(body.data(), body.size(), true)) return reader.why();
    {
      std::lock_guard lock(mutex_);
      ++stats_.messages;
    }
    try {
      CheckBodyCrc(header, body);
      Handle(header, body);
    } catch (const MessageError& e) {
      Reject(e.reason(), device);
    }
  }
  return reader.why();
}

void EmStreamClient::Handle(const MessageHeader& header, std::span<const std::uint8_t> body) {
  const double t_s = header.timestamp_s();
  if (header.type == "STATUS") {
    const IgtlStatus s = DecodeStatus(header, body);
    std::lock_guard lock(mutex_);
    ++stats_.status_by_code[std::to_string(s.code)];
    return;
  }
  const auto metadata = DecodeMetadata(header, body);
  if (header.type == "TRANSFORM") {
    const TrackedTransform t = DecodeTransform(header, body, options_.limits);
    Offer(t.name, t_s, t, EmStatusOf(metadata, "TransformStatus"));
    return;
  }
  // TDATA: one timestamp for all its elements.
  const std::vector<TrackedTransform> elements = DecodeTrackingData(header, body, options_.limits);
  if (options_.tool.empty()) {
    // Several tools in one message, or another than the one streaming so far: ambiguous
    // before any of its elements is recorded.
    std::lock_guard lock(mutex_);
    bool ambiguous = false;
    for (const TrackedTransform& e : elements) {
      ambiguous = ambiguous || e.name != elements.front().name ||
                  (!stats_.tool.empty() && e.name != stats_.tool);
    }
    if (ambiguous) {
      std::string names;
      for (const TrackedTransform& e : elements) ++stats_.tools_seen[e.name];
      for (const auto& [name, n] : stats_.tools_seen) names += (names.empty() ? "" : ", ") + name;
      stats_.tool_error =
          "several tools stream (" + names + "): choose one with --em-tool NAME; recording stopped";
      return;
    }
  }
  bool ours = false;
  for (const TrackedTransform& e : elements) {
    if (!options_.tool.empty() && e.name != options_.tool) {
      std::lock_guard lock(mutex_);
      ++stats_.tools_seen[e.name];
      continue;
    }
    ours = true;
    Offer(e.name, t_s, e, EmStatusOf(metadata, e.name + "Status"));
  }
  if (!ours && !options_.tool.empty()) {
    throw MessageError("unknown_device",
                       "TDATA '" + header.device_name + "' has no element '" + options_.tool + "'");
  }
}

void EmStreamClient::Offer(const std::string& tool, double t_s, const TrackedTransform& pose,
                           const std::string& status) {
  EmStreamSample s;
  {
    std::lock_guard lock(mutex_);
    ++stats_.tools_seen[tool];
    if (!options_.tool.empty() && tool != options_.tool) {
      // Counted as a rejection by Handle's caller: a TRANSFORM of another tool.
      throw MessageError("unknown_device", "TRANSFORM of '" + tool + "', recording '" +
                                               options_.tool + "' (--em-tool)");
    }
    if (stats_.tool.empty()) stats_.tool = tool;  // the first tool streaming
    if (tool != stats_.tool) {
      std::string names;
      for (const auto& [name, n] : stats_.tools_seen) names += (names.empty() ? "" : ", ") + name;
      stats_.tool_error =
          "several tools stream (" + names + "): choose one with --em-tool NAME; recording stopped";
    }
    if (!stats_.tool_error.empty()) return;  // ambiguous: nothing more is recorded
    if (any_sample_ && t_s <= stats_.last_t_s) {
      ++(t_s == stats_.last_t_s ? stats_.duplicates_skipped : stats_.older_skipped);
      return;
    }
    s.tool = tool;
    s.t_s = t_s;
    s.tool_to_tracker = pose.transform;
    s.position_mm = pose.transform.translation();
    if (!status.empty() && status != "OK") {
      s.valid = false;
      s.dropout_reason = status;
    } else if (status.empty() && EmIsExactIdentity(pose.transform)) {
      s.valid = false;
      s.dropout_reason = "identity";
    }
    if (!s.valid) s.position_mm.setZero();
    if (!any_sample_) stats_.first_t_s = t_s;
    any_sample_ = true;
    stats_.last_t_s = t_s;
    ++stats_.samples;
    if (s.valid)
      ++stats_.valid_samples;
    else
      ++stats_.dropouts_by_reason[s.dropout_reason];
  }
  try {
    options_.on_sample(s);
  } catch (const std::exception& e) {  // the sink (a full disk, …): counted, the stream goes on
    std::lock_guard lock(mutex_);
    ++stats_.rejected;
    ++stats_.rejected_by_reason["sink_error"];
    ++stats_.rejected_by_device["sink_error " + tool];
    stats_.last_error = e.what();
  }
}

}  // namespace echoservo::imaging::openigtlink
