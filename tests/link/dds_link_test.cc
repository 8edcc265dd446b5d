// The DDS link between two participants of one process over loopback: round trips of
// each type, the QoS of each topic and what it does, the ROS 2 names, bad samples
// rejected and counted, participant options. Waits are bounded by generous timeouts;
// nothing asserts on timing.
#include "link/dds_link.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <limits>
#include <mutex>
#include <regex>
#include <string>
#include <vector>

#include "link/clock.h"
#include "tests/link/link_test_util.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::link {
namespace {

using echoservo::testing::Eventually;
using echoservo::testing::MakeCommand;
using echoservo::testing::MakeState;
using echoservo::testing::MakeTarget;
using echoservo::testing::ProcessDomain;

constexpr double kMatchTimeoutS = 15.0;

ParticipantOptions Loopback(const std::string& name) {
  ParticipantOptions o;
  o.domain_id = ProcessDomain();
  o.name = name;
  o.loopback_only = true;
  return o;
}

// Both sides of the pair have matched (each side learns of the other on its own).
template <class Sample>
bool Matched(const Publisher<Sample>& pub, const Subscriber<Sample>& sub) {
  return pub.WaitForSubscribers(1, kMatchTimeoutS) && sub.WaitForPublishers(1, kMatchTimeoutS);
}

// Publishes `make(k)` (k = 1, 2, ...) every 20 ms until the subscriber takes one
// (best-effort samples sent before the reader knows the writer are lost); returns the
// sample it took and the one published with that sequence number.
template <class Sample, class Make>
std::pair<Sample, Sample> RoundTrip(Publisher<Sample>& pub, Subscriber<Sample>& sub, Make make) {
  EXPECT_TRUE(Matched(pub, sub));
  std::vector<Sample> sent;
  Sample got;
  for (std::uint64_t k = 1; k <= 500; ++k) {
    sent.push_back(make(k));
    EXPECT_TRUE(pub.Publish(sent.back()));
    if (sub.WaitTakeLatest(got, 0.02)) {
      const auto same = std::find_if(sent.begin(), sent.end(), [&](const Sample& s) {
        return s.sequence_number == got.sequence_number;
      });
      EXPECT_NE(same, sent.end()) << "received a sample never published";
      return {got, same == sent.end() ? got : *same};
    }
  }
  ADD_FAILURE() << "nothing received on " << sub.topic_name();
  return {got, got};
}

class DdsLinkTest : public ::testing::Test {
 protected:
  Participant tracker_{Loopback("tracker")};
  Participant servo_{Loopback("servo")};
};

TEST_F(DdsLinkTest, TargetRoundTrip) {
  TargetPublisher pub(tracker_);
  TargetSubscriber sub(servo_);
  const auto [got, sent] =
      RoundTrip(pub, sub, [](std::uint64_t seq) { return MakeTarget(seq, NowS()); });
  EXPECT_EQ(got, sent);
}

TEST_F(DdsLinkTest, StateRoundTrip) {
  StatePublisher pub(servo_);
  StateSubscriber sub(tracker_);
  const auto [got, sent] =
      RoundTrip(pub, sub, [](std::uint64_t seq) { return MakeState(seq, NowS()); });
  EXPECT_EQ(got, sent);
}

TEST_F(DdsLinkTest, CommandRoundTrip) {
  CommandPublisher pub(tracker_);
  CommandSubscriber sub(servo_);
  const auto [got, sent] = RoundTrip(pub, sub, [](std::uint64_t seq) {
    return MakeCommand(seq, NowS(), ServoAction::kSetStandoff);
  });
  EXPECT_EQ(got, sent);
}

TEST_F(DdsLinkTest, TopicAndTypeNamesFollowRos2) {
  TargetPublisher target(tracker_);
  StatePublisher state(servo_);
  CommandSubscriber command(servo_);
  // ROS 2 maps topic /echoservo/x to DDS topic rt/echoservo/x and message pkg/msg/T to
  // the DDS type pkg::msg::dds_::T_.
  EXPECT_EQ(target.topic_name(), "rt/echoservo/target_estimate");
  EXPECT_EQ(target.type_name(), "echoservo_msgs::msg::dds_::TargetEstimate_");
  EXPECT_EQ(state.topic_name(), "rt/echoservo/catheter_state");
  EXPECT_EQ(state.type_name(), "echoservo_msgs::msg::dds_::CatheterState_");
  EXPECT_EQ(command.topic_name(), "rt/echoservo/servo_command");
  EXPECT_EQ(command.type_name(), "echoservo_msgs::msg::dds_::ServoCommand_");
  const std::regex ros2_type("[a-z][a-z0-9_]*::msg::dds_::[A-Z][A-Za-z0-9]*_");
  for (const std::string& type : {target.type_name(), state.type_name(), command.type_name()}) {
    EXPECT_TRUE(std::regex_match(type, ros2_type)) << type;
  }
  EXPECT_EQ(target.type_name(), std::string(kTargetType));
  EXPECT_EQ(state.topic_name(), std::string(kStateTopic));
  EXPECT_EQ(command.type_name(), std::string(kCommandType));
}

TEST_F(DdsLinkTest, QosBestEffortStreamReliableStateAndCommands) {
  TargetPublisher target_pub(tracker_);
  TargetSubscriber target_sub(servo_);
  StatePublisher state_pub(servo_);
  CommandSubscriber command_sub(servo_);
  for (const EndpointQos& q : {target_pub.qos(), target_sub.qos()}) {
    EXPECT_FALSE(q.reliable);
    EXPECT_FALSE(q.transient_local);
    EXPECT_LE(q.depth, 4);
    EXPECT_EQ(q.liveliness_lease_s, kLivelinessLeaseS);
  }
  EXPECT_EQ(target_pub.qos().depth, 1);
  EXPECT_TRUE(state_pub.qos().reliable);
  EXPECT_TRUE(state_pub.qos().transient_local);
  EXPECT_EQ(state_pub.qos().liveliness_lease_s, kLivelinessLeaseS);
  EXPECT_TRUE(command_sub.qos().reliable);
  EXPECT_TRUE(command_sub.qos().transient_local);
  EXPECT_GT(command_sub.qos().depth, 1);
  // Commands accept publishers of any lease (a ROS 2 node's default is infinite).
  EXPECT_EQ(command_sub.qos().liveliness_lease_s, std::numeric_limits<double>::infinity());
}

TEST_F(DdsLinkTest, ReliableCommandsAllDeliveredInOrder) {
  CommandPublisher pub(tracker_);
  std::mutex mu;
  std::vector<ServoCommandSample> got;
  CommandSubscriber sub(servo_, {}, [&](const ServoCommandSample& s, double) {
    std::lock_guard lock(mu);
    got.push_back(s);
  });
  ASSERT_TRUE(Matched(pub, sub));
  const std::vector<ServoAction> burst = {ServoAction::kEnable, ServoAction::kSetStandoff,
                                          ServoAction::kSetStandoff, ServoAction::kDisable,
                                          ServoAction::kStop};
  ASSERT_LE(burst.size(), static_cast<std::size_t>(pub.qos().depth));
  std::vector<ServoCommandSample> sent;
  for (std::size_t i = 0; i < burst.size(); ++i) {
    sent.push_back(MakeCommand(i + 1, NowS(), burst[i]));
    ASSERT_TRUE(pub.Publish(sent.back()));
  }
  ASSERT_TRUE(Eventually([&] {
    std::lock_guard lock(mu);
    return got.size() >= sent.size();
  }));
  std::lock_guard lock(mu);
  EXPECT_EQ(got, sent);
  EXPECT_EQ(sub.stats().sequence_gaps, 0u);
}

TEST_F(DdsLinkTest, TransientLocalStateReachesLateSubscriber) {
  StatePublisher pub(servo_);
  const CatheterStateSample last = MakeState(42, NowS());
  ASSERT_TRUE(pub.Publish(MakeState(41, NowS())));
  ASSERT_TRUE(pub.Publish(last));
  StateSubscriber late(tracker_);  // created after both were published
  CatheterStateSample got;
  ASSERT_TRUE(late.WaitTakeLatest(got, kMatchTimeoutS));
  EXPECT_EQ(got, last);  // keep-last 1: the newest state only
  EXPECT_EQ(late.stats().validation.accepted, 1u);
}

TEST_F(DdsLinkTest, BestEffortTargetSubscriberKeepsOnlyTheLatest) {
  TargetPublisher pub(tracker_);
  std::atomic<std::uint64_t> newest{0}, first{0};
  TargetSubscriber sub(servo_, {}, [&](const TargetEstimateSample& s, double) {
    if (first == 0) first = s.sequence_number;
    newest = s.sequence_number;
  });
  ASSERT_TRUE(Matched(pub, sub));
  // A burst nobody takes, then (in case the last one was lost) one more every 0.2 s
  // until the newest arrives.
  constexpr std::uint64_t kBurst = 10;
  std::uint64_t seq = 0;
  while (seq < kBurst) ASSERT_TRUE(pub.Publish(MakeTarget(++seq, NowS())));
  ASSERT_TRUE(Eventually([&] {
    if (newest == seq) return true;
    if (!Eventually([&] { return newest == seq; }, 0.2)) {
      EXPECT_TRUE(pub.Publish(MakeTarget(++seq, NowS())));
    }
    return newest == seq;
  }));
  TargetEstimateSample got;
  ASSERT_TRUE(Eventually([&] { return sub.TryTakeLatest(got); }));
  EXPECT_EQ(got.sequence_number, seq);
  EXPECT_FALSE(sub.TryTakeLatest(got));  // nothing newer
  const SubscriberStats stats = sub.stats();
  EXPECT_EQ(stats.overwritten, stats.validation.accepted - 1);
  // Best effort over a transport (intra-process delivery is off): samples before the first
  // one received may be lost too, and are not gaps between accepted samples.
  EXPECT_EQ(stats.sequence_gaps + stats.validation.accepted, seq - first + 1);
}

TEST_F(DdsLinkTest, BadTargetsRejectedCountedAndSubscriberKeepsServing) {
  TargetPublisher pub(tracker_);
  TargetSubscriber sub(servo_);
  ASSERT_TRUE(Matched(pub, sub));
  const ValidationLimits limits;
  const auto bad = [&](std::uint64_t seq, Rejection reason) {
    TargetEstimateSample s = MakeTarget(seq, NowS());
    switch (reason) {
      case Rejection::kNonFinite:
        s.target_mm.x() = std::numeric_limits<double>::quiet_NaN();
        break;
      case Rejection::kOutOfRange:
        s.motion.frequency_hz = 2.0 * limits.max_frequency_hz;
        break;
      case Rejection::kBadMotionModel:
        s.motion.sin_mm.pop_back();
        break;
      case Rejection::kFutureTimestamp:
        s.publication_time_s = NowS() + 60.0;
        break;
      case Rejection::kStaleTimestamp:
        s = MakeTarget(seq, NowS() - 10.0 * limits.max_target_age_s);
        break;
      case Rejection::kPublishedBeforeAcquired:
        s.publication_time_s = s.acquisition_time_s - 0.01;
        break;
      case Rejection::kCount:
        break;
    }
    return s;
  };
  // Best effort into a keep-last-1 reader: one bad sample at a time (a burst would leave
  // only its last in the reader's history), repeated until its reason has been counted.
  std::uint64_t seq = 0;
  for (int r = 0; r < static_cast<int>(Rejection::kCount); ++r) {
    const auto reason = static_cast<Rejection>(r);
    EXPECT_TRUE(Eventually([&] {
      EXPECT_TRUE(pub.Publish(bad(++seq, reason)));
      return Eventually([&] { return sub.stats().validation.count(reason) > 0; }, 0.2);
    })) << ToString(reason);
  }
  TargetEstimateSample got;
  EXPECT_FALSE(sub.TryTakeLatest(got));
  EXPECT_EQ(sub.stats().validation.accepted, 0u);
  // Still serving: a good estimate goes through.
  const auto [taken, sent] =
      RoundTrip(pub, sub, [&](std::uint64_t) { return MakeTarget(++seq, NowS()); });
  EXPECT_EQ(taken.sequence_number, sent.sequence_number);
  EXPECT_GE(sub.stats().validation.accepted, 1u);
}

TEST_F(DdsLinkTest, BadCommandsRejectedAndCountedExactly) {
  // Reliable: every bad command arrives once and is counted once, by reason.
  CommandPublisher pub(tracker_);
  CommandSubscriber sub(servo_);
  ASSERT_TRUE(Matched(pub, sub));
  const ValidationLimits limits;
  ServoCommandSample nan_standoff = MakeCommand(1, NowS(), ServoAction::kEnable);
  nan_standoff.standoff_mm = std::numeric_limits<double>::quiet_NaN();
  ServoCommandSample far_standoff = MakeCommand(2, NowS(), ServoAction::kSetStandoff);
  far_standoff.standoff_mm = 2.0 * limits.max_standoff_mm;
  ServoCommandSample unknown =
      MakeCommand(3, NowS(), static_cast<ServoAction>(kMaxServoAction + 7));
  const ServoCommandSample old_enable =
      MakeCommand(4, NowS() - 10.0 * limits.max_command_age_s, ServoAction::kEnable);
  const ServoCommandSample future = MakeCommand(5, NowS() + 60.0, ServoAction::kStop);
  for (const ServoCommandSample& s : {nan_standoff, far_standoff, unknown, old_enable, future}) {
    ASSERT_TRUE(pub.Publish(s));
  }
  const ServoCommandSample stop = MakeCommand(6, NowS(), ServoAction::kStop);
  ASSERT_TRUE(pub.Publish(stop));
  ServoCommandSample got;
  ASSERT_TRUE(sub.WaitTakeLatest(got, kMatchTimeoutS));
  EXPECT_EQ(got, stop);
  const SubscriberStats stats = sub.stats();
  EXPECT_EQ(stats.received, 6u);
  EXPECT_EQ(stats.validation.accepted, 1u);
  EXPECT_EQ(stats.validation.count(Rejection::kNonFinite), 1u);
  EXPECT_EQ(stats.validation.count(Rejection::kOutOfRange), 2u);
  EXPECT_EQ(stats.validation.count(Rejection::kStaleTimestamp), 1u);
  EXPECT_EQ(stats.validation.count(Rejection::kFutureTimestamp), 1u);
}

TEST_F(DdsLinkTest, PublisherGoneWhenItLeaves) {
  TargetSubscriber sub(servo_);
  {
    TargetPublisher pub(tracker_);
    ASSERT_TRUE(sub.WaitForPublishers(1, kMatchTimeoutS));
    ASSERT_TRUE(Eventually([&] { return sub.stats().alive_publishers == 1; }));
    EXPECT_FALSE(sub.stats().publisher_gone());
  }
  EXPECT_TRUE(Eventually([&] { return sub.stats().publisher_gone(); }));
}

TEST_F(DdsLinkTest, TooManyHarmonicsThrowsAtPublish) {
  TargetPublisher pub(tracker_);
  TargetEstimateSample s = MakeTarget(1, NowS());
  s.motion.cos_mm.assign(kMaxHarmonics + 1, 0.0);
  s.motion.sin_mm.assign(kMaxHarmonics + 1, 0.0);
  echoservo::testing::ExpectContains(
      echoservo::testing::InvalidArgumentMessage([&] { pub.Publish(s); }), "harmonics");
}

// The shipped XML profile (the platform's deterministic fallback) and the default
// transports both discover within the process.
TEST(DdsLinkDiscovery, LoopbackXmlProfile) {
  ParticipantOptions o;
  o.domain_id = ProcessDomain();
  o.profiles_file = ECHOSERVO_LOOPBACK_PROFILE;
  o.profile = "echoservo_loopback";
  Participant a(o);
  Participant b(o);
  CommandPublisher pub(a);
  CommandSubscriber sub(b);
  const auto [got, sent] = RoundTrip(
      pub, sub, [](std::uint64_t seq) { return MakeCommand(seq, NowS(), ServoAction::kDisable); });
  EXPECT_EQ(got, sent);
}

TEST(DdsLinkDiscovery, DefaultTransports) {
  ParticipantOptions o;
  o.domain_id = ProcessDomain();
  Participant a(o);
  Participant b(o);
  StatePublisher pub(a);
  StateSubscriber sub(b);
  const auto [got, sent] =
      RoundTrip(pub, sub, [](std::uint64_t seq) { return MakeState(seq, NowS()); });
  EXPECT_EQ(got, sent);
}

TEST(DdsLinkDiscovery, SecurityPropertiesPassThrough) {
  // A property Fast DDS does not act on is carried without effect: the hook DDS-Security
  // settings will use.
  ParticipantOptions o = Loopback("props");
  o.properties = {{"echoservo.test.property", "1"}};
  Participant p(o);
  EXPECT_EQ(p.domain_id(), o.domain_id);
}

TEST(ParticipantOptionsTest, BadOptionsThrowNamingTheOption) {
  using echoservo::testing::ExpectContains;
  using echoservo::testing::InvalidArgumentMessage;
  const auto message = [](const ParticipantOptions& o) {
    return InvalidArgumentMessage([&] { o.Validate(); });
  };
  ParticipantOptions domain;
  domain.domain_id = 300;
  ExpectContains(message(domain), "domain_id");
  ParticipantOptions interface;
  interface.interfaces = {"eth0.local"};
  ExpectContains(message(interface), "interfaces");
  ParticipantOptions peer;
  peer.initial_peers = {"10.0.0.2:99999"};
  ExpectContains(message(peer), "initial_peers");
  ParticipantOptions both;
  both.loopback_only = true;
  both.initial_peers = {"10.0.0.2"};
  ExpectContains(message(both), "loopback_only");
  ParticipantOptions profile;
  profile.profile = "x";
  ExpectContains(message(profile), "profiles_file");
  ParticipantOptions missing_file;
  missing_file.profiles_file = "/nonexistent/profile.xml";
  ExpectContains(InvalidArgumentMessage([&] { Participant p(missing_file); }), "profiles_file");
  ParticipantOptions good;
  good.initial_peers = {"10.0.0.2", "10.0.0.3:7412"};
  good.interfaces = {"10.0.0.1"};
  EXPECT_NO_THROW(good.Validate());
}

}  // namespace
}  // namespace echoservo::link
