#include "apps/commands/link_flags.h"

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <stdexcept>
#include <string>
#include <vector>

#include "link/dds_link.h"
#include "link/security.h"

namespace echoservo::apps {
namespace {

std::atomic<bool> g_stop{false};

extern "C" void OnStopSignal(int) { g_stop.store(true); }

}  // namespace

void AddLinkFlags(CLI::App& cmd, LinkFlags& f) {
  cmd.add_option("--dds-domain", f.domain, "DDS domain of the tracker ↔ servo link")
      ->check(CLI::Range(0, 232));
  cmd.add_flag("--loopback", f.loopback, "this host only: UDP on 127.0.0.1, no multicast");
  cmd.add_option("--interface", f.interfaces,
                 "IPv4 address of an interface to use (repeatable; default: all)");
  cmd.add_option(
      "--peer", f.peers,
      "unicast discovery peer A.B.C.D[:PORT] where multicast does not pass (repeatable)");
  cmd.add_flag("--no-shm", f.no_shm, "UDP only (no shared-memory transport)");
  cmd.add_option(
      "--secure", f.secure_dir,
      "DDS-Security: the credential directory of `echoservo security init DIR` (authentication, "
      "access control, encryption)");
  cmd.add_option(
      "--secure-identity", f.secure_identity,
      "the participant's identity in the --secure directory (default: this command's role)");
}

std::vector<std::pair<std::string, std::string>> SecureProperties(const std::string& dir,
                                                                  const std::string& role) {
  try {
    return link::SecurityProperties(link::CheckSecurityDir(dir, role));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("--secure " + dir + " (identity '" + role + "'): " + e.what());
  }
}

link::ParticipantOptions ToParticipantOptions(const LinkFlags& f, const std::string& name,
                                              const std::string& role) {
  link::ParticipantOptions o;
  o.domain_id = f.domain;
  o.name = name;
  o.loopback_only = f.loopback;
  o.interfaces = f.interfaces;
  o.initial_peers = f.peers;
  o.shared_memory = !f.no_shm;  // loopback_only sets its own transports (UDP only)
  if (!f.secure_identity.empty() && f.secure_dir.empty())
    throw std::invalid_argument("--secure-identity needs --secure DIR");
  if (!f.secure_dir.empty())
    o.properties =
        SecureProperties(f.secure_dir, f.secure_identity.empty() ? role : f.secure_identity);
  o.Validate();
  return o;
}

std::string DescribeLink(const LinkFlags& f) {
  std::string text = "DDS domain " + std::to_string(f.domain) + " (";
  auto list = [](const std::vector<std::string>& items) {
    std::string out;
    for (const std::string& i : items) out += (out.empty() ? "" : ", ") + i;
    return out;
  };
  if (f.loopback) {
    text += "UDPv4 on 127.0.0.1 only, --loopback";
  } else {
    text += f.no_shm ? "UDPv4 only" : "UDPv4 + shared memory";
    text += f.interfaces.empty() ? ", all interfaces" : ", interfaces " + list(f.interfaces);
    text += f.peers.empty() ? ", multicast discovery" : ", unicast peers " + list(f.peers);
  }
  if (!f.secure_dir.empty()) text += ", DDS-Security " + f.secure_dir;
  return text + ")";
}

void InstallStopSignals() {
  std::signal(SIGINT, OnStopSignal);
  std::signal(SIGTERM, OnStopSignal);
}

bool StopRequested() { return g_stop.load(); }

}  // namespace echoservo::apps
