// The DDS link between two processes on this host (the test and link_test_peer, spawned):
// targets published by the peer are received here, a STOP published here reaches the
// peer, and a killed publisher is reported gone through liveliness. In the loopback-only
// mode and with the default transports. Timeouts are generous; no timing assertions.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "link/clock.h"
#include "link/dds_link.h"
#include "tests/link/link_test_util.h"

extern char** environ;

namespace echoservo::link {
namespace {

using echoservo::testing::Eventually;
using echoservo::testing::MakeCommand;
using echoservo::testing::MakeTarget;
using echoservo::testing::ProcessDomain;

// A child process that is killed if the test leaves before it exits.
class Peer {
 public:
  explicit Peer(std::vector<std::string> args) {
    args.insert(args.begin(), LINK_TEST_PEER);
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, argv[0], nullptr, nullptr, argv.data(), environ) != 0) pid_ = -1;
  }
  ~Peer() {
    if (pid_ > 0) Kill();
  }
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;

  bool running() const { return pid_ > 0; }
  // The exit status, or -1 when it did not exit within `timeout_s` (then it is killed).
  int Wait(double timeout_s) {
    int status = 0;
    const bool exited =
        Eventually([&] { return waitpid(pid_, &status, WNOHANG) == pid_; }, timeout_s);
    if (!exited) {
      Kill();
      return -1;
    }
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  void Kill() {
    kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
};

class TwoProcessTest : public ::testing::TestWithParam<bool> {
 protected:
  bool loopback() const { return GetParam(); }
  std::string mode() const { return loopback() ? "loopback" : "default"; }
  ParticipantOptions Options() const {
    ParticipantOptions o;
    o.domain_id = ProcessDomain();
    o.name = "two_process_test";
    o.loopback_only = loopback();
    return o;
  }
};

TEST_P(TwoProcessTest, TargetsFromThePeerArrive) {
  Participant participant(Options());
  TargetSubscriber sub(participant);
  Peer peer({"publish-targets", std::to_string(ProcessDomain()), mode(), "100"});
  ASSERT_TRUE(peer.running());
  TargetEstimateSample got;
  ASSERT_TRUE(sub.WaitTakeLatest(got, 30.0));
  // The peer built it with MakeTarget(seq, acquisition time): the same fields here.
  EXPECT_EQ(got, MakeTarget(got.sequence_number, got.acquisition_time_s));
  EXPECT_EQ(peer.Wait(60.0), 0);
  EXPECT_GE(sub.stats().validation.accepted, 1u);
  EXPECT_EQ(sub.stats().validation.total_rejected(), 0u);
}

TEST_P(TwoProcessTest, StopFromHereReachesThePeer) {
  Participant participant(Options());
  CommandPublisher pub(participant);
  Peer peer({"await-stop", std::to_string(ProcessDomain()), mode()});
  ASSERT_TRUE(peer.running());
  ASSERT_TRUE(pub.WaitForSubscribers(1, 30.0));
  ASSERT_TRUE(pub.Publish(MakeCommand(1, NowS(), ServoAction::kStop)));
  EXPECT_EQ(peer.Wait(30.0), 0);
}

TEST_P(TwoProcessTest, KilledPublisherReportedGone) {
  Participant participant(Options());
  TargetSubscriber sub(participant);
  Peer peer({"publish-targets", std::to_string(ProcessDomain()), mode(), "0"});
  ASSERT_TRUE(peer.running());
  TargetEstimateSample got;
  ASSERT_TRUE(sub.WaitTakeLatest(got, 30.0));
  ASSERT_TRUE(Eventually([&] { return sub.stats().alive_publishers == 1; }, 30.0));
  EXPECT_FALSE(sub.stats().publisher_gone());
  peer.Kill();  // no goodbye: only the liveliness lease can tell
  EXPECT_TRUE(Eventually([&] { return sub.stats().publisher_gone(); }, 30.0));
  EXPECT_GE(sub.stats().liveliness_lost, 1u);
  EXPECT_EQ(sub.stats().matched_publishers, 1u);  // still matched: the participant lease is longer
}

INSTANTIATE_TEST_SUITE_P(Transports, TwoProcessTest, ::testing::Values(true, false),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return p.param ? "Loopback" : "Default";
                         });

}  // namespace
}  // namespace echoservo::link
