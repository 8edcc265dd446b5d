#include "live/detection_serve.h"

#include <cstdio>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "imaging/igtl/detection_server.h"
#include "live/tracker_node.h"

namespace echoservo::live {

DetectionServe::DetectionServe(const DetectionServeOptions& f, const std::string& command)
    : command_(command) {
  if (f.port < 0) {
    if (f.volumes)
      throw std::invalid_argument(command + " --igtl-volumes: needs --igtl-serve PORT");
    if (!f.bind.empty())
      throw std::invalid_argument(command + " --igtl-bind: needs --igtl-serve PORT");
    return;
  }
  if (f.port > 65535) {
    throw std::invalid_argument(command + " --igtl-serve: port " + std::to_string(f.port) +
                                " is outside [0, 65535]");
  }
  imaging::openigtlink::DetectionServerOptions o;
  o.port = f.port;
  o.send_volumes = f.volumes;
  if (!f.bind.empty()) o.bind_address = f.bind;
  server_ = std::make_unique<imaging::openigtlink::DetectionServer>(o);
  try {
    server_->Start();
  } catch (const std::exception& e) {
    throw std::runtime_error(command + " --igtl-serve " + std::to_string(f.port) + ": " + e.what());
  }
  std::fprintf(stderr, "%s: serving detections over OpenIGTLink on %s:%d%s\n", command.c_str(),
               o.bind_address.c_str(), server_->port(), f.volumes ? " (with volumes)" : "");
}

DetectionServe::~DetectionServe() = default;

int DetectionServe::port() const { return server_ ? server_->port() : -1; }

void DetectionServe::OnTracked(const TrackedVolume& r, const imaging::Volume& volume,
                               double acquired_unix_s) {
  if (!server_) return;
  imaging::openigtlink::DetectionSample s;
  s.acquired_unix_s = acquired_unix_s;
  const tracking::CatheterDetection& d = r.detection;
  s.found = r.error.empty() && d.found;
  if (s.found) {
    s.tip_mm = d.tip_mm;
    s.axis = d.axis.direction;
    if (d.target_found) s.target_mm = d.target_mm;
    s.confidence = d.confidence;
  }
  server_->Publish(s, &volume);
}

std::string DetectionServe::Finish(bool quiet) {
  if (!server_) return "null";
  server_->Stop();
  const imaging::openigtlink::DetectionServerStats s = server_->stats();
  nlohmann::json clients = nlohmann::json::array();
  for (const auto& c : s.clients) {
    clients.push_back({{"peer", c.peer},
                       {"connected", c.connected},
                       {"end", c.end},
                       {"messages_sent", c.messages_sent},
                       {"messages_dropped", c.messages_dropped},
                       {"bytes_sent", c.bytes_sent},
                       {"messages_received", c.messages_received}});
  }
  const nlohmann::json out = {{"port", server_->port()},
                              {"samples_published", s.samples_published},
                              {"samples_dropped", s.samples_dropped},
                              {"samples_encoded", s.samples_encoded},
                              {"encode_errors", s.encode_errors},
                              {"clients_accepted", s.clients_accepted},
                              {"clients_refused", s.clients_refused},
                              {"clients_disconnected", s.clients_disconnected},
                              {"clients_stalled", s.clients_stalled},
                              {"sent",
                               {{"TRANSFORM", s.sent_transform},
                                {"POINT", s.sent_points},
                                {"STATUS", s.sent_status},
                                {"IMAGE", s.sent_image}}},
                              {"bytes_sent", s.bytes_sent},
                              {"messages_dropped", s.messages_dropped},
                              {"client_messages_received", s.client_messages_received},
                              {"client_messages_rejected", s.client_messages_rejected},
                              {"send_latency_ms_p50", s.send_latency_ms_p50},
                              {"send_latency_ms_p99", s.send_latency_ms_p99},
                              {"clients", clients}};
  if (!quiet) {
    std::fprintf(stderr,
                 "%s: OpenIGTLink: %llu volume(s) published to %llu client(s); %llu message(s) "
                 "dropped (queue full), %llu client(s) cut off (stalled)%s%s\n",
                 command_.c_str(), static_cast<unsigned long long>(s.samples_published),
                 static_cast<unsigned long long>(s.clients_accepted),
                 static_cast<unsigned long long>(s.messages_dropped),
                 static_cast<unsigned long long>(s.clients_stalled),
                 s.encode_errors ? "; not encoded: " : "", s.last_encode_error.c_str());
  }
  return out.dump();
}

}  // namespace echoservo::live
