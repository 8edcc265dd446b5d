// The streaming commands end to end, as a user runs them: `echoservo scanner` serves
// simulated volumes over OpenIGTLink on loopback, `echoservo ingest` receives and
// validates them; `scanner --record` writes a sequence with ground truth that `replay`
// and `info` read back.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

using ::echoservo::testing::RunCli;
using ::echoservo::testing::RunShell;
using ::echoservo::testing::ShellQuote;

TEST(StreamCli, ScannerToIngestOverLoopback) {
  const int port = 20000 + static_cast<int>(::getpid() % 20000);
  // The server waits for its client, streams 20 phantom-free simulated frames at 25 vol/s
  // and exits; it runs in the background of a shell.
  const std::string server = std::string(ECHOSERVO_CLI) + " scanner --port " +
                             std::to_string(port) +
                             " --frames 20 --rate 25 --json > /dev/null 2>&1 &";
  ASSERT_EQ(std::system(server.c_str()), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the scanner builds its scene
  const auto r = RunCli("ingest --connect 127.0.0.1:" + std::to_string(port) +
                        " --frames 20 --duration 20 --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frames"].get<int>(), 20);
  EXPECT_EQ(j["rejected"].get<int>(), 0);
  EXPECT_TRUE(j["reasons"].empty());
  EXPECT_GE(j["latency_ms"]["p99"].get<double>(), j["latency_ms"]["p50"].get<double>());
}

TEST(StreamCli, RecordReplayAndInfo) {
  testing::TempDir dir("stream_cli", true);
  const auto seq = dir.path() / "sim.igs.mha";
  const auto rec = RunCli("scanner --record " + ShellQuote(seq.string()) + " --frames 4 --json");
  ASSERT_EQ(rec.rc, 0) << rec.err;
  const auto info = RunCli("info " + ShellQuote(seq.string()) + " --json");
  ASSERT_EQ(info.rc, 0) << info.err;
  const auto i = nlohmann::json::parse(info.out);
  EXPECT_EQ(i["frames"].get<int>(), 4);
  EXPECT_EQ(i["dims"], nlohmann::json::array({160, 148, 208}));
  const auto fields = i["frame_fields"].get<std::vector<std::string>>();
  for (const char* f :
       {"CatheterTip", "CatheterAxisPoint", "CatheterAxisDirection", "Target", "Timestamp"}) {
    EXPECT_NE(std::find(fields.begin(), fields.end(), f), fields.end()) << f;
  }
  const auto replay = RunCli("replay " + ShellQuote(seq.string()) + " --rate max --json");
  ASSERT_EQ(replay.rc, 0) << replay.err;
  const auto p = nlohmann::json::parse(replay.out);
  EXPECT_EQ(p["frames"].get<int>(), 4);
  EXPECT_EQ(p["rejected"].get<int>(), 0);
}

TEST(StreamCli, IngestRejectsABadAddressClearly) {
  const auto r = RunCli("ingest --connect nowhere --duration 1");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("HOST:PORT"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace echoservo
