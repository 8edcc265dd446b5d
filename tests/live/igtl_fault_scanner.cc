// A scanner that fails on purpose, for the live-process fault tests
// (tests/live/live_processes_test.cc): it serves the simulated scanner's volumes as
// OpenIGTLink IMAGE messages to one client, stamped with the wall clock as a live scanner
// does, then
//   1. after FIRST_S seconds sends the first half of the next IMAGE message and closes the
//      connection (a stream truncated mid-volume), and stops listening;
//   2. stays away for GAP_S seconds (the client's reconnects are refused: a disconnect);
//   3. listens again on the same port and serves SECOND_S seconds more (the reconnect).
// Usage: igtl_fault_scanner PORT_FILE FIRST_S GAP_S SECOND_S
// Writes the port it listens on to PORT_FILE, prints a JSON summary at the end.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "imaging/igtl/image_message.h"
#include "imaging/igtl/tcp.h"
#include "imaging/sim/simulated_scanner.h"

namespace {

namespace igtl = echoservo::imaging::openigtlink;
using Clock = std::chrono::steady_clock;

double WallS() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

struct Phase {
  long frames = 0;
  bool client = false;
};

// Serves `seconds` of volumes at the scanner's rate to the first client that connects
// (within 30 s). With `truncate`, then writes half of one more message before closing.
Phase Serve(echoservo::imaging::sim::SimulatedScanner& scanner, const igtl::tcp::Fd& listener,
            double seconds, bool truncate, std::size_t& truncated_bytes) {
  Phase p;
  igtl::tcp::Fd client = igtl::tcp::Accept(listener, 30000);
  if (!client.valid()) return p;
  p.client = true;
  igtl::tcp::SetNoDelay(client.get());
  const double period_s = 1.0 / scanner.nominal_rate_hz();
  const Clock::time_point start = Clock::now();
  std::vector<std::uint8_t> message;
  for (long k = 0;; ++k) {
    const Clock::time_point due = start + std::chrono::duration_cast<Clock::duration>(
                                              std::chrono::duration<double>(k * period_s));
    std::this_thread::sleep_until(due);
    std::optional<echoservo::imaging::SourceFrame> f = scanner.Next();
    if (!f) break;
    f->volume.set_timestamp_s(WallS());
    igtl::EncodeImage(f->volume, {}, message);
    const bool last = std::chrono::duration<double>(Clock::now() - start).count() >= seconds;
    if (last && truncate) {
      truncated_bytes = message.size() / 2;
      igtl::tcp::WriteAll(client.get(), message.data(), truncated_bytes, 2000);
      break;
    }
    if (last) break;
    if (igtl::tcp::WriteAll(client.get(), message.data(), message.size(), 2000) !=
        igtl::tcp::IoResult::kOk)
      break;
    ++p.frames;
  }
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: igtl_fault_scanner PORT_FILE FIRST_S GAP_S SECOND_S\n");
    return 2;
  }
  try {
    const double first_s = std::stod(argv[2]), gap_s = std::stod(argv[3]),
                 second_s = std::stod(argv[4]);
    echoservo::imaging::sim::SimulatedScannerOptions options;
    echoservo::imaging::sim::SimulatedScanner scanner(options);
    int port = 0;
    std::size_t truncated_bytes = 0;
    Phase first, second;
    {
      igtl::tcp::Fd listener = igtl::tcp::Listen("127.0.0.1", 0, port);
      std::ofstream(argv[1]) << port << "\n";
      first = Serve(scanner, listener, first_s, true, truncated_bytes);
    }  // the listener closes: connections are refused during the gap
    std::this_thread::sleep_for(std::chrono::duration<double>(gap_s));
    {
      int again = 0;
      igtl::tcp::Fd listener = igtl::tcp::Listen("127.0.0.1", port, again);
      second = Serve(scanner, listener, second_s, false, truncated_bytes);
    }
    std::printf(
        "{\"port\": %d, \"first_frames\": %ld, \"truncated_bytes\": %zu, \"second_client\": %s, "
        "\"second_frames\": %ld}\n",
        port, first.frames, truncated_bytes, second.client ? "true" : "false", second.frames);
    return first.client && second.client ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "igtl_fault_scanner: %s\n", e.what());
    return 1;
  }
}
