// The DDS link's command-line flags, shared by `track`, `servo` and `command`: domain,
// loopback-only mode, interfaces and unicast peers for two hosts, shared memory off
// (link/dds_link.h ParticipantOptions; docs/dds.md).
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}
namespace echoservo::link {
struct ParticipantOptions;
}

namespace echoservo::apps {

struct LinkFlags {
  int domain = 0;
  bool loopback = false;
  std::vector<std::string> interfaces;
  std::vector<std::string> peers;
  bool no_shm = false;
};

void AddLinkFlags(CLI::App& cmd, LinkFlags& flags);
// Throws std::invalid_argument naming the flag (ParticipantOptions::Validate).
link::ParticipantOptions ToParticipantOptions(const LinkFlags& flags, const std::string& name);

// SIGINT/SIGTERM set a flag a command's loop polls (a clean stop: the servo retracts
// nothing by itself, it stops and its last state goes out).
void InstallStopSignals();
bool StopRequested();

}  // namespace echoservo::apps
