// The ingest client's connection events (imaging/igtl/ingest.h IngestOptions::on_event), what
// `track --connect` logs: every failed attempt with its number, the errno text and the
// back-off before the next; a server that closes is reported with why. Loopback sockets only;
// no timing is asserted.
#include <gtest/gtest.h>

#include <cerrno>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "imaging/igtl/ingest.h"
#include "imaging/igtl/tcp.h"

namespace echoservo::imaging::openigtlink {
namespace {

using Kind = ConnectionEvent::Kind;

struct Events {
  std::mutex m;
  std::vector<ConnectionEvent> list;
  void Add(const ConnectionEvent& e) {
    std::lock_guard lock(m);
    list.push_back(e);
  }
};

TEST(IngestEvents, EveryRefusedAttemptIsReportedWithErrnoAndBackOff) {
  int port = 0;
  { tcp::Fd probe = tcp::Listen("127.0.0.1", 0, port); }  // a port nobody listens on now
  IngestOptions io;
  io.host = "127.0.0.1";
  io.port = port;
  io.reconnect_initial_s = 0.01;
  io.reconnect_max_s = 0.04;
  io.max_connect_failures = 3;
  Events events;
  io.on_event = [&events](const ConnectionEvent& e) { events.Add(e); };
  IngestClient ingest(io);
  ingest.Start();
  EXPECT_FALSE(ingest.Next());  // gives up after 4 failures
  ingest.Stop();
  ASSERT_EQ(events.list.size(), 5u);
  const double waits[] = {0.01, 0.02, 0.04, 0.0};  // doubling, bounded; none after the last
  for (int i = 0; i < 4; ++i) {
    const ConnectionEvent& e = events.list[static_cast<std::size_t>(i)];
    EXPECT_EQ(e.kind, Kind::kConnectFailed);
    EXPECT_EQ(e.attempt, i + 1);
    EXPECT_EQ(e.error_number, ECONNREFUSED);
    EXPECT_EQ(e.error, "connection refused (ECONNREFUSED)");
    EXPECT_DOUBLE_EQ(e.retry_in_s, waits[i]);
    EXPECT_EQ(e.frames, 0);
  }
  EXPECT_EQ(events.list.back().kind, Kind::kGaveUp);
  EXPECT_EQ(ingest.stats().last_connect_error, "connection refused (ECONNREFUSED)");
}

TEST(IngestEvents, AServerThatClosesIsReportedAndRetried) {
  int port = 0;
  tcp::Fd listener = tcp::Listen("127.0.0.1", 0, port);
  IngestOptions io;
  io.host = "127.0.0.1";
  io.port = port;
  io.reconnect_initial_s = 0.01;
  io.reconnect_max_s = 0.02;
  Events events;
  io.on_event = [&events](const ConnectionEvent& e) { events.Add(e); };
  IngestClient ingest(io);
  ingest.Start();
  // Accept the client and close at once, twice: two connections, two disconnects.
  for (int i = 0; i < 2; ++i) {
    tcp::Fd client;
    while (!client.valid()) client = tcp::Accept(listener, 100);
  }
  while (ingest.stats().connections < 2 || [&] {
    std::lock_guard lock(events.m);
    int n = 0;
    for (const auto& e : events.list) n += e.kind == Kind::kDisconnected;
    return n < 2;
  }()) {
    std::this_thread::yield();
  }
  ingest.Stop();
  std::lock_guard lock(events.m);
  ASSERT_GE(events.list.size(), 4u);
  EXPECT_EQ(events.list[0].kind, Kind::kConnected);
  EXPECT_EQ(events.list[0].attempt, 1);
  EXPECT_EQ(events.list[1].kind, Kind::kDisconnected);
  EXPECT_EQ(events.list[1].error, "closed by the server");
  EXPECT_GT(events.list[1].retry_in_s, 0.0);
  EXPECT_EQ(events.list[2].kind, Kind::kConnected);
}

}  // namespace
}  // namespace echoservo::imaging::openigtlink
