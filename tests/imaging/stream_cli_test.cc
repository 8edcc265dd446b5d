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

// The scanner's summary says a client that left is a client disconnected, apart from frames
// (none lost here: the phantom's 30 frames went to the client that stayed).
TEST(StreamCli, ScannerSummaryCountsADisconnectedClientApartFromFrames) {
  testing::TempDir dir("stream_cli", true);
  const int port = 20000 + static_cast<int>((::getpid() + 7919) % 20000);
  const std::string cli = std::string(ECHOSERVO_CLI);
  const std::string summary = (dir.path() / "summary.txt").string();
  const std::string ingest = cli + " ingest --connect 127.0.0.1:" + std::to_string(port);
  // Two clients: one takes 3 frames and leaves, the other takes all 30.
  const auto r = RunShell(cli + " scanner --source phantom --port " + std::to_string(port) +
                          " --frames 30 --rate 30 --min-clients 2 > " + ShellQuote(summary) +
                          " 2>/dev/null & sleep 0.5; " + ingest +
                          " --frames 30 --duration 20 > /dev/null 2>&1 & " + ingest +
                          " --frames 3 --duration 20 > /dev/null; wait");
  ASSERT_EQ(r.rc, 0) << r.err;
  const std::string text = testing::ReadFile(summary);
  EXPECT_NE(text.find("sent 30 frames to 2 clients; 1 client disconnected, 0 clients cut off "
                      "for stalling; 0 frames reached no client"),
            std::string::npos)
      << text;
  EXPECT_EQ(text.find("dropped"), std::string::npos) << text;
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
