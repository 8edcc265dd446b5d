// DDS-Security on the link (link/security.h, docs/dds.md "Security"): the credentials
// `InitSecurityDir` writes check out; bad credential directories are errors naming the
// file; and on a secured domain only a properly credentialed operator's commands reach
// the servo's command subscriber — not a participant without security, not one with a
// complete set from another CA, not one whose permissions were forged (signed by another
// CA), and not the tracker (its permissions do not grant servo_command: DDS refuses it
// the writer). Loopback only, a test-private domain; no timing assertions.
#include "link/security.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "link/clock.h"
#include "link/dds_link.h"
#include "tests/link/link_test_util.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::link {
namespace {

namespace fs = std::filesystem;
using echoservo::testing::Eventually;
using echoservo::testing::MakeCommand;
using echoservo::testing::ProcessDomain;

std::string Read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void Write(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

// The message of the std::invalid_argument `f` throws ("" when it does not).
template <class F>
std::string InvalidArgument(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

ParticipantOptions Options(std::vector<std::pair<std::string, std::string>> properties = {}) {
  ParticipantOptions o;
  o.domain_id = ProcessDomain();
  o.name = "security_test";
  o.loopback_only = true;
  o.properties = std::move(properties);
  return o;
}

TEST(SecurityInit, WritesCaIdentitiesAndSignedDocumentsThatCheckOut) {
  const echoservo::testing::TempDir dir("sec_init");
  const auto files = InitSecurityDir(dir.str());
  EXPECT_GE(files.size(), 4u + 4u * 4u);
  for (const std::string& role : SecurityRoles()) {
    SCOPED_TRACE(role);
    const SecurityFiles f = CheckSecurityDir(dir.str(), role);
    EXPECT_EQ(f.certificate, (dir.path() / role / "cert.pem").string());
    struct stat st {};
    ASSERT_EQ(::stat(f.private_key.c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 0777, 0600u);
    const auto props = SecurityProperties(f);
    EXPECT_EQ(props.front().first, "dds.sec.auth.plugin");
    for (const auto& [name, value] : props)
      if (value.rfind("file://", 0) == 0) {
        EXPECT_TRUE(fs::exists(value.substr(7))) << name;
      }
  }
  struct stat st {};
  ASSERT_EQ(::stat((dir.path() / "ca" / "ca_key.pem").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  // Who may publish what.
  const auto publishes = [&](const std::string& role, std::string_view topic) {
    const std::string xml = Read(dir.path() / role / "permissions.xml");
    const auto pub = xml.find("<publish>"), end = xml.find("</publish>");
    return pub != std::string::npos && xml.substr(pub, end - pub).find(topic) != std::string::npos;
  };
  EXPECT_TRUE(publishes("operator", kCommandTopic));
  EXPECT_FALSE(publishes("servo", kCommandTopic));
  EXPECT_FALSE(publishes("tracker", kCommandTopic));
  EXPECT_FALSE(publishes("monitor", kCommandTopic));
  EXPECT_TRUE(publishes("tracker", kTargetTopic));
  EXPECT_FALSE(publishes("operator", kTargetTopic));
  EXPECT_TRUE(publishes("servo", kStateTopic));
  const std::string governance = Read(dir.path() / "governance.xml");
  EXPECT_NE(governance.find("<enable_join_access_control>true"), std::string::npos);
  EXPECT_NE(governance.find("<data_protection_kind>ENCRYPT"), std::string::npos);
  EXPECT_NE(Read(dir.path() / "governance.p7s").find("multipart/signed"), std::string::npos);
}

TEST(SecurityInit, BadOptionsAndExistingCredentialsThrow) {
  const echoservo::testing::TempDir dir("sec_opts");
  SecurityInitOptions o;
  o.participants = {"tracker", "pilot"};
  EXPECT_NE(InvalidArgument([&] { InitSecurityDir(dir.str(), o); }).find("'pilot'"),
            std::string::npos);
  o.participants = {"servo", "servo"};
  EXPECT_NE(InvalidArgument([&] { InitSecurityDir(dir.str(), o); }).find("twice"),
            std::string::npos);
  o.participants = {"servo"};
  o.validity_days = 0;
  EXPECT_NE(InvalidArgument([&] { InitSecurityDir(dir.str(), o); }).find("validity_days"),
            std::string::npos);
  o.validity_days = 30;
  InitSecurityDir(dir.str(), o);
  EXPECT_NE(InvalidArgument([&] { InitSecurityDir(dir.str(), o); }).find("ca_cert.pem exists"),
            std::string::npos);
  o.overwrite = true;
  EXPECT_NO_THROW(InitSecurityDir(dir.str(), o));
}

TEST(SecurityDir, BadDirectoriesAreErrorsNamingTheFile) {
  const echoservo::testing::TempDir root("sec_bad", true);
  const fs::path a = root.path() / "a", b = root.path() / "b";
  InitSecurityDir(a.string());
  InitSecurityDir(b.string());
  const auto error = [](const fs::path& dir, const std::string& who) {
    return InvalidArgument([&] { CheckSecurityDir(dir.string(), who); });
  };
  // Not a directory.
  EXPECT_NE(error(root.path() / "none", "servo")
                .find((root.path() / "none").string() + ": not a directory"),
            std::string::npos);
  // A directory made for other participants.
  SecurityInitOptions some;
  some.participants = {"tracker", "operator"};
  InitSecurityDir((root.path() / "some").string(), some);
  std::string e = error(root.path() / "some", "servo");
  EXPECT_NE(e.find((root.path() / "some" / "servo" / "cert.pem").string() + ": missing"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("operator"), std::string::npos) << e;
  // Each required file missing, in turn.
  for (const fs::path& rel :
       {fs::path("ca/ca_cert.pem"), fs::path("governance.p7s"), fs::path("servo/cert.pem"),
        fs::path("servo/key.pem"), fs::path("servo/permissions.p7s")}) {
    const fs::path c = root.path() / "copy";
    fs::remove_all(c);
    fs::copy(a, c, fs::copy_options::recursive);
    fs::remove(c / rel);
    e = error(c, "servo");
    EXPECT_NE(e.find((c / rel).string() + ": missing"), std::string::npos) << rel << ": " << e;
  }
  const auto fresh = [&] {
    const fs::path c = root.path() / "mixed";
    fs::remove_all(c);
    fs::copy(a, c, fs::copy_options::recursive);
    return c;
  };
  // A certificate (with its key) from another CA.
  fs::path c = fresh();
  fs::copy_file(b / "servo" / "cert.pem", c / "servo" / "cert.pem",
                fs::copy_options::overwrite_existing);
  fs::copy_file(b / "servo" / "key.pem", c / "servo" / "key.pem",
                fs::copy_options::overwrite_existing);
  e = error(c, "servo");
  EXPECT_NE(e.find((c / "servo" / "cert.pem").string() + ": not issued by"), std::string::npos)
      << e;
  // A key that is not the certificate's.
  c = fresh();
  fs::copy_file(a / "tracker" / "key.pem", c / "servo" / "key.pem",
                fs::copy_options::overwrite_existing);
  e = error(c, "servo");
  EXPECT_NE(e.find((c / "servo" / "key.pem").string() + ": does not match"), std::string::npos)
      << e;
  // Garbage in place of the certificate.
  c = fresh();
  Write(c / "servo" / "cert.pem", "not a certificate\n");
  e = error(c, "servo");
  EXPECT_NE(e.find((c / "servo" / "cert.pem").string() + ": not a PEM certificate"),
            std::string::npos)
      << e;
  // Permissions edited after signing (servo_command granted to the servo).
  c = fresh();
  std::string p7s = Read(c / "servo" / "permissions.p7s");
  const auto at = p7s.find("rt/echoservo/catheter_state");
  ASSERT_NE(at, std::string::npos);
  p7s.replace(at, std::string("rt/echoservo/catheter_state").size(), "rt/echoservo/servo_command");
  Write(c / "servo" / "permissions.p7s", p7s);
  e = error(c, "servo");
  EXPECT_NE(e.find((c / "servo" / "permissions.p7s").string() + ": its signature does not verify"),
            std::string::npos)
      << e;
  // Governance signed by another CA.
  c = fresh();
  fs::copy_file(b / "governance.p7s", c / "governance.p7s", fs::copy_options::overwrite_existing);
  e = error(c, "servo");
  EXPECT_NE(e.find((c / "governance.p7s").string() + ": its signature does not verify"),
            std::string::npos)
      << e;
  // Another participant's permissions (the tracker's, in the servo's place).
  c = fresh();
  fs::copy_file(a / "tracker" / "permissions.p7s", c / "servo" / "permissions.p7s",
                fs::copy_options::overwrite_existing);
  e = error(c, "servo");
  EXPECT_NE(e.find((c / "servo" / "permissions.p7s").string() + ": grants nothing"),
            std::string::npos)
      << e;
  // The good directory checks out.
  EXPECT_NO_THROW(CheckSecurityDir(a.string(), "servo"));
}

// Publishes ENABLE commands until stopped (an attacker: whatever it can publish).
class Spammer {
 public:
  explicit Spammer(CommandPublisher& pub) : pub_(pub), thread_([this] { Run(); }) {}
  ~Spammer() {
    stop_ = true;
    thread_.join();
  }
  Spammer(const Spammer&) = delete;
  Spammer& operator=(const Spammer&) = delete;

 private:
  void Run() {
    for (std::uint64_t seq = 1; !stop_; ++seq) {
      pub_.Publish(MakeCommand(seq, NowS(), ServoAction::kEnable));
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  CommandPublisher& pub_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

TEST(SecureLink, OnlyACredentialedOperatorsCommandsReachTheServo) {
  const echoservo::testing::TempDir root("sec_link", true);
  const fs::path a = root.path() / "a", b = root.path() / "b";
  InitSecurityDir(a.string());
  InitSecurityDir(b.string());

  Participant servo(Options(SecurityProperties(CheckSecurityDir(a.string(), "servo"))));
  CommandSubscriber commands(servo);

  // 1. No security at all.
  Participant plain(Options());
  CommandPublisher plain_pub(plain);
  // 2. A complete, self-consistent set from another CA (its own "operator").
  Participant foreign(Options(SecurityProperties(CheckSecurityDir(b.string(), "operator"))));
  CommandPublisher foreign_pub(foreign);
  // 3. The real tracker identity with forged permissions: a grant of servo_command to the
  //    tracker's subject, signed by another CA (which this participant trusts for
  //    permissions, so it starts; the servo checks them against its own CA).
  std::string grant = Read(a / "tracker" / "permissions.xml");
  const auto at = grant.find(kTargetTopic);
  ASSERT_NE(at, std::string::npos);
  grant.replace(at, kTargetTopic.size(), kCommandTopic);
  Write(root.path() / "forged.xml", grant);
  SignSecurityDocument((root.path() / "forged.xml").string(), (b / "ca" / "ca_cert.pem").string(),
                       (b / "ca" / "ca_key.pem").string(), (root.path() / "forged.p7s").string());
  SecurityFiles forged = CheckSecurityDir(a.string(), "tracker");
  forged.permissions_ca = (b / "ca" / "ca_cert.pem").string();
  forged.governance = (b / "governance.p7s").string();
  forged.permissions = (root.path() / "forged.p7s").string();
  Participant forger(Options(SecurityProperties(forged)));
  CommandPublisher forger_pub(forger);
  // 4. The real tracker: its permissions do not grant servo_command, DDS refuses the writer.
  Participant tracker(Options(SecurityProperties(CheckSecurityDir(a.string(), "tracker"))));
  EXPECT_THROW(CommandPublisher refused(tracker), std::runtime_error);

  {
    Spammer s1(plain_pub), s2(foreign_pub), s3(forger_pub);
    // Authentication of a legitimate peer takes ~1 s here; give the attackers 4 s.
    std::this_thread::sleep_for(std::chrono::seconds(4));
    EXPECT_EQ(commands.stats().received, 0u);
    EXPECT_EQ(commands.stats().matched_publishers, 0u);
    EXPECT_EQ(plain_pub.matched_subscribers(), 0u);
    EXPECT_EQ(foreign_pub.matched_subscribers(), 0u);
    EXPECT_EQ(forger_pub.matched_subscribers(), 0u);

    // The operator, while the attackers keep publishing.
    Participant op(Options(SecurityProperties(CheckSecurityDir(a.string(), "operator"))));
    CommandPublisher op_pub(op);
    ASSERT_TRUE(op_pub.WaitForSubscribers(1, 30.0));
    ASSERT_TRUE(op_pub.Publish(MakeCommand(7, NowS(), ServoAction::kStop)));
    ServoCommandSample got;
    ASSERT_TRUE(commands.WaitTakeLatest(got, 15.0));
    EXPECT_EQ(got.action, ServoAction::kStop);
    EXPECT_EQ(got.sequence_number, 7u);
    std::this_thread::sleep_for(std::chrono::seconds(1));
    EXPECT_EQ(commands.stats().received, 1u);  // the operator's STOP only
    EXPECT_EQ(commands.stats().validation.accepted, 1u);
    EXPECT_EQ(commands.stats().matched_publishers, 1u);
  }
}

// Secured participants still deliver all three topics between the roles that may.
TEST(SecureLink, RolesDeliverWhatTheyMay) {
  const echoservo::testing::TempDir root("sec_roles", true);
  InitSecurityDir(root.str());
  const auto secured = [&](const std::string& role) {
    return std::make_unique<Participant>(
        Options(SecurityProperties(CheckSecurityDir(root.str(), role))));
  };
  auto tracker = secured("tracker"), servo = secured("servo"), monitor = secured("monitor");
  TargetPublisher targets(*tracker);
  StatePublisher states(*servo);
  TargetSubscriber servo_targets(*servo);
  StateSubscriber tracker_states(*tracker);
  TargetSubscriber monitor_targets(*monitor);
  EXPECT_THROW(TargetPublisher refused(*servo), std::runtime_error);
  EXPECT_THROW(StatePublisher refused(*monitor), std::runtime_error);
  ASSERT_TRUE(targets.WaitForSubscribers(2, 30.0));
  ASSERT_TRUE(states.WaitForSubscribers(1, 30.0));
  TargetEstimateSample t;
  CatheterStateSample s;
  ASSERT_TRUE(Eventually([&] {
    targets.Publish(echoservo::testing::MakeTarget(1, NowS()));
    return servo_targets.WaitTakeLatest(t, 0.05);
  }));
  ASSERT_TRUE(Eventually([&] {
    targets.Publish(echoservo::testing::MakeTarget(2, NowS()));
    return monitor_targets.WaitTakeLatest(t, 0.05);
  }));
  ASSERT_TRUE(states.Publish(echoservo::testing::MakeState(3, NowS())));
  ASSERT_TRUE(tracker_states.WaitTakeLatest(s, 15.0));
  EXPECT_EQ(s.sequence_number, 3u);
}

}  // namespace
}  // namespace echoservo::link
