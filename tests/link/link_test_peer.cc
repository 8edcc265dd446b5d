// The other process of the two-process DDS tests (tests/link/two_process_test.cc):
//   link_test_peer publish-targets DOMAIN loopback|default COUNT
//     waits for a target subscriber, publishes COUNT estimates (0: until killed, at most
//     60 s) every 5 ms from sequence number 1 (tests/link/link_test_util.h MakeTarget);
//   link_test_peer await-stop DOMAIN loopback|default
//     subscribes to commands; exits 0 when a STOP arrives, 2 after 30 s without one.
// Exit 1 for bad arguments.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "link/clock.h"
#include "link/dds_link.h"
#include "tests/link/link_test_util.h"

namespace {

using namespace echoservo::link;

int PublishTargets(Participant& participant, long count) {
  TargetPublisher pub(participant);
  if (!pub.WaitForSubscribers(1, 30.0)) return 2;
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  for (long seq = 1; count == 0 || seq <= count; ++seq) {
    pub.Publish(echoservo::testing::MakeTarget(static_cast<std::uint64_t>(seq), NowS()));
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    if (std::chrono::steady_clock::now() > end) break;
  }
  return 0;
}

int AwaitStop(Participant& participant) {
  CommandSubscriber sub(participant);
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  ServoCommandSample command;
  while (std::chrono::steady_clock::now() < end) {
    if (sub.WaitTakeLatest(command, 0.1) && command.action == ServoAction::kStop) return 0;
  }
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(
        stderr,
        "usage: link_test_peer publish-targets|await-stop DOMAIN loopback|default [COUNT]\n");
    return 1;
  }
  const std::string role = argv[1];
  ParticipantOptions options;
  options.domain_id = std::atoi(argv[2]);
  options.name = "link_test_peer";
  options.loopback_only = std::string(argv[3]) == "loopback";
  Participant participant(options);
  if (role == "publish-targets" && argc == 5)
    return PublishTargets(participant, std::atol(argv[4]));
  if (role == "await-stop") return AwaitStop(participant);
  std::fprintf(stderr, "link_test_peer: bad role or arguments\n");
  return 1;
}
