// The DDS link's command-line flags, shared by `track`, `servo` and `command`: domain,
// loopback-only mode, interfaces and unicast peers for two hosts, shared memory off, and
// DDS-Security credentials (--secure DIR from `echoservo security init`, the identity
// being the command's role unless --secure-identity names another) (link/dds_link.h
// ParticipantOptions, link/security.h; docs/dds.md).
#pragma once

#include <string>
#include <utility>
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
  std::string secure_dir;       // empty: no DDS-Security
  std::string secure_identity;  // empty: the command's role
};

void AddLinkFlags(CLI::App& cmd, LinkFlags& flags);
// `role` is the participant's identity in a --secure directory (tracker, servo, operator).
// Throws std::invalid_argument naming the flag (ParticipantOptions::Validate) or, for
// --secure, the credential file and what is wrong with it (link::CheckSecurityDir).
link::ParticipantOptions ToParticipantOptions(const LinkFlags& flags, const std::string& name,
                                              const std::string& role);
// The dds.sec.* properties of `role` in `dir` (--secure), errors prefixed with the flag.
std::vector<std::pair<std::string, std::string>> SecureProperties(const std::string& dir,
                                                                  const std::string& role);

// Where a participant with these flags looks for peers, for "no peer" messages:
// "DDS domain 0 (UDPv4 + shared memory, multicast discovery)", "DDS domain 61 (UDPv4 on
// 127.0.0.1 only, --loopback)", with interfaces, peers and --secure when given.
std::string DescribeLink(const LinkFlags& flags);

// SIGINT/SIGTERM set a flag that a command's loop polls, so it ends cleanly: the servo
// leaves its loop, prints its summary and its participant leaves the domain.
void InstallStopSignals();
bool StopRequested();

}  // namespace echoservo::apps
