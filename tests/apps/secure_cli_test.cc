// DDS-Security from the command line (docs/dds.md "Security"): `echoservo security init`
// writes credentials; a servo started with --secure applies the operator's command and
// nobody else's — a `command` without credentials, with a complete set from another CA,
// or with the tracker's identity (whose permissions do not grant servo_command) never
// reaches it, and its commands_applied counts only the operator's; bad --secure
// directories are clear errors naming the file. Loopback only, test-private domains.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using testing::ReadFile;
using testing::RunCli;
using testing::RunShell;
using testing::ShellQuote;

const std::string kCli = ShellQuote(ECHOSERVO_CLI);

TEST(SecureCli, InitWritesCredentialsThatCheckOut) {
  const testing::TempDir dir("sec_cli_init", true);
  const std::string d = (dir.path() / "sec").string();
  auto r = RunCli("security init " + ShellQuote(d) +
                  " --participants tracker,servo,operator --days 30 --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out, nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << r.out;
  EXPECT_EQ(j["participants"].size(), 3u);
  for (const char* f : {"ca/ca_cert.pem", "ca/ca_key.pem", "governance.p7s", "operator/cert.pem",
                        "operator/key.pem", "operator/permissions.p7s"})
    EXPECT_TRUE(fs::exists(fs::path(d) / f)) << f;
  EXPECT_FALSE(fs::exists(fs::path(d) / "monitor"));
  r = RunCli("security check " + ShellQuote(d) + " --participant operator --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("dds.sec.crypto.plugin"), std::string::npos) << r.out;
  // Again without --force: refused, naming the file.
  r = RunCli("security init " + ShellQuote(d) + " --participants servo");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find((fs::path(d) / "ca" / "ca_cert.pem").string() + " exists"),
            std::string::npos)
      << r.err;
  r = RunCli("security init " + ShellQuote(d) + " --participants pilot --force");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("'pilot'"), std::string::npos) << r.err;
}

TEST(SecureCli, OnlyTheCredentialedOperatorsCommandIsApplied) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "SecureLink.OnlyACredentialedOperatorsCommandsReachTheServo takes the same DDS-Security "
      "path in process");
  const testing::TempDir dir("sec_cli_cmd", true);
  const std::string sec = (dir.path() / "sec").string(), other = (dir.path() / "other").string();
  ASSERT_EQ(RunCli("security init " + ShellQuote(sec)).rc, 0);
  ASSERT_EQ(RunCli("security init " + ShellQuote(other)).rc, 0);
  const fs::path servo = dir.path() / "servo.json";
  const std::string link = " --loopback --dds-domain 67";
  const auto out = [&](const char* name) { return ShellQuote((dir.path() / name).string()); };
  // The three attempts run side by side while the servo is up (each waits 5 s for a servo
  // that accepts it); then the operator's ENABLE.
  const auto r = RunShell(
      kCli + " servo --duration 16 --json --secure " + ShellQuote(sec) + link + " > " +
      ShellQuote(servo.string()) + " & sleep 1; " + "(" + kCli +
      " command enable --standoff 6 --wait 5" + link + " > " + out("plain.out") + " 2> " +
      out("plain.err") + "; echo $? > " + out("plain.rc") + ") & " + "(" + kCli +
      " command enable --standoff 6 --wait 5 --secure " + ShellQuote(other) + link + " > " +
      out("other.out") + " 2> " + out("other.err") + "; echo $? > " + out("other.rc") + ") & " +
      "(" + kCli + " command enable --standoff 6 --wait 5 --secure " + ShellQuote(sec) +
      " --secure-identity tracker" + link + " > " + out("tracker.out") + " 2> " +
      out("tracker.err") + "; echo $? > " + out("tracker.rc") + ") & " + "sleep 7; " + kCli +
      " command enable --standoff 6 --wait 6 --json --secure " + ShellQuote(sec) + link +
      "; rc=$?; wait; exit $rc");
  ASSERT_EQ(r.rc, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("\"applied\": true"), std::string::npos) << r.out;
  for (const char* who : {"plain", "other", "tracker"}) {
    SCOPED_TRACE(who);
    EXPECT_EQ(ReadFile(dir.path() / (std::string(who) + ".rc")), "1\n");
  }
  EXPECT_NE(ReadFile(dir.path() / "plain.err").find("no servo"), std::string::npos);
  // Where it looked (domain, transport, the security folder) and why nobody answered.
  const std::string other_err = ReadFile(dir.path() / "other.err");
  EXPECT_NE(other_err.find("no servo on DDS domain 67 ("), std::string::npos) << other_err;
  EXPECT_NE(other_err.find("DDS-Security"), std::string::npos) << other_err;
  EXPECT_NE(other_err.find("servo_command that accepts these credentials"), std::string::npos)
      << other_err;
  EXPECT_NE(ReadFile(dir.path() / "tracker.err").find("do not grant publishing it"),
            std::string::npos)
      << ReadFile(dir.path() / "tracker.err");
  const auto s = nlohmann::json::parse(ReadFile(servo), nullptr, false);
  ASSERT_FALSE(s.is_discarded()) << ReadFile(servo);
  EXPECT_EQ(s["commands_applied"].get<int>(), 1);  // the operator's ENABLE, nobody else's
  EXPECT_EQ(s["commands_rejected"].get<int>(), 0);
  EXPECT_EQ(s["limit_violations"].get<int>(), 0);
  // Before the operator's command the servo stayed idle: its first mode change is to a
  // following mode, after the attempts (≥ 6 s in).
  ASSERT_GE(s["timeline"].size(), 2u);
  EXPECT_EQ(s["timeline"][0]["mode"], "idle");
  EXPECT_GE(s["timeline"][1]["t_s"].get<double>(), 6.0);
}

TEST(SecureCli, BadSecureDirectoriesAreErrorsNamingTheFile) {
  const testing::TempDir dir("sec_cli_bad", true);
  const fs::path sec = dir.path() / "sec";
  ASSERT_EQ(
      RunCli("security init " + ShellQuote(sec.string()) + " --participants tracker,operator").rc,
      0);
  const std::string link = " --loopback --dds-domain 68";
  // No such directory.
  auto r =
      RunCli("servo --duration 1 --secure " + ShellQuote((dir.path() / "none").string()) + link);
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find((dir.path() / "none").string() + ": not a directory"), std::string::npos)
      << r.err;
  // The wrong participant: no servo credentials in it.
  r = RunCli("servo --duration 1 --secure " + ShellQuote(sec.string()) + link);
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find((sec / "servo" / "cert.pem").string() + ": missing"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("identity 'servo'"), std::string::npos) << r.err;
  r = RunCli("command stop --wait 1 --secure " + ShellQuote(sec.string()) +
             " --secure-identity monitor" + link);
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find((sec / "monitor" / "cert.pem").string()), std::string::npos) << r.err;
  // A missing key.
  fs::remove(sec / "tracker" / "key.pem");
  r = RunCli("track --sim --duration 1 --secure " + ShellQuote(sec.string()) + link);
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find((sec / "tracker" / "key.pem").string() + ": missing"), std::string::npos)
      << r.err;
  r = RunCli("demo --duration 5 --secure " + ShellQuote(sec.string()));
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find((sec / "tracker" / "key.pem").string() + ": missing"), std::string::npos)
      << r.err;
  // --secure-identity alone.
  r = RunCli("command stop --wait 1 --secure-identity operator" + link);
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--secure-identity needs --secure"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace echoservo
