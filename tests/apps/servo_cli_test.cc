// `echoservo servo`'s real-time options and deadline watchdog, end to end: slow hardware
// reads injected on purpose (--inject-slow-read) make the 1 kHz cycles overrun; a short run
// of overruns holds the tip, one read as long as the retraction limit retracts it; the JSON
// summary times every cycle; bad real-time options are errors naming the option.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo {
namespace {

using testing::RunCli;

// A servo without a tracker on a private loopback domain for 1.2 s.
nlohmann::json RunServo(const std::string& extra, int domain) {
  const auto r = RunCli("servo --loopback --dds-domain " + std::to_string(domain) +
                        " --duration 1.2 --json " + extra);
  EXPECT_EQ(r.rc, 0) << r.err;
  return nlohmann::json::parse(r.out);
}

TEST(ServoCli, AShortRunOfSlowReadsHoldsAndTheServoResumes) {
  // Ten reads of 3 ms from t = 0.3 s: ten cycles overrun and the loop falls ~20 cycles behind,
  // which it catches up within a millisecond: a run of overruns of ~30 ms, past K = 10 and
  // short of the 50 ms retraction limit; 50 on-time cycles later the hold ends.
  const auto j = RunServo("--inject-slow-read 0.3,0.31,3", 71);
  const auto& t = j["timing"];
  EXPECT_EQ(t["cycles"].get<int>(), 1201);
  EXPECT_GE(t["overruns"].get<int>(), 10);
  EXPECT_GE(t["max_consecutive_overruns"].get<int>(), 10);
  EXPECT_GE(t["cycle_duration_us"]["max"].get<double>(), 3000.0);
  EXPECT_GE(j["deadline"]["holds"].get<int>(), 1);
  // The one hold and no retraction, when the servo thread runs at SCHED_FIFO in a Release
  // build; a sanitizer build, or an ordinary thread beside other tests, may miss deadlines
  // of its own for longer.
  if (!testing::kUnderSanitizers && j["realtime"]["fifo"].get<bool>()) {
    EXPECT_EQ(j["deadline"]["retracts"].get<int>(), 0) << j["timing"].dump();
  }
}

TEST(ServoCli, OneReadAsLongAsTheRetractionLimitRetracts) {
  // One 80 ms read at t = 0.3 s: no cycle ends on time for 80 ms > 50 ms.
  const auto j = RunServo("--inject-slow-read 0.3,0.301,80", 72);
  EXPECT_GE(j["timing"]["cycle_duration_us"]["max"].get<double>(), 80000.0);
  EXPECT_GE(j["timing"]["wakeup_latency_us"]["max"].get<double>(), 79000.0);
  EXPECT_GE(j["deadline"]["retracts"].get<int>(), 1);
  EXPECT_DOUBLE_EQ(j["deadline"]["retract_after_ms"].get<double>(), 50.0);
}

TEST(ServoCli, RealTimeIsGrantedOrItsRefusalIsSaid) {
  const auto j = RunServo("--rt-priority 60", 73);
  const auto& rt = j["realtime"];
  EXPECT_TRUE(rt["requested"].get<bool>());
  if (rt["fifo"].get<bool>()) {
    EXPECT_EQ(rt["priority"].get<int>(), 60);
  } else {
    EXPECT_FALSE(rt["refusals"].empty()) << rt.dump();
  }
  if (!rt["memory_locked"].get<bool>()) {
    EXPECT_FALSE(rt["refusals"].empty()) << rt.dump();
  }
  const auto off = RunServo("--no-realtime", 74);
  EXPECT_FALSE(off["realtime"]["requested"].get<bool>());
  EXPECT_FALSE(off["realtime"]["fifo"].get<bool>());
  EXPECT_TRUE(off["realtime"]["refusals"].empty());
}

TEST(ServoCli, BadRealTimeOptionsNameTheOption) {
  const std::pair<const char*, const char*> cases[] = {
      {"--rt-priority 120", "--rt-priority"},
      {"--rt-priority 0", "--rt-priority"},
      {"--servo-cpu 4096", "--servo-cpu"},
      {"--servo-cpu -2", "--servo-cpu"},
      {"--deadline-hold-after 0", "--deadline-hold-after"},
      {"--deadline-retract-after-ms 3", "--deadline-retract-after-ms"},
      {"--deadline-resume-after 0", "--deadline-resume-after"},
      {"--cpu-latency-us -5", "--cpu-latency-us"},
      {"--inject-slow-read 1,0.5,3", "--inject-slow-read"},
      {"--inject-slow-read 0.1,0.2", "--inject-slow-read"},
      {"--inject-slow-read 0.1,0.2,5000", "--inject-slow-read"},
  };
  for (const auto& [args, option] : cases) {
    const auto r = RunCli(std::string("servo --loopback --duration 0.1 ") + args);
    EXPECT_NE(r.rc, 0) << args;
    EXPECT_NE(r.err.find(option), std::string::npos) << args << ": " << r.err;
  }
}

}  // namespace
}  // namespace echoservo
