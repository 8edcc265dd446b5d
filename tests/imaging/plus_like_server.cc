// plus_like_server: a PLUS-like OpenIGTLink tracker server built only on libOpenIGTLink
// (igtl::ServerSocket, igtl::TransformMessage, igtl::TimeStamp; no echoservo code), the
// independent peer of scripts/em_stream_check.sh.
//
// Streams the pose of one tool (TRANSFORM, device name --tool) at --rate Hz for --duration s
// to the first client, stamped with the wall clock (s since the Unix epoch), the way
// PlusServer does: with --resend each pose is sent twice (PLUS resends the newest pose when
// nothing new arrived), with --other-tool a second tool's pose goes out beside it. Every
// distinct pose sent is written to --sent CSV (t_s as on the wire, 32.32 fixed point, and
// position in mm), so the receiver's log can be checked against it. A client that goes away
// is waited for again. With --replay CSV (an em.csv: t_s,x_mm,y_mm,z_mm,status) it streams
// that log's positions at its own pace instead, a row whose status is not OK as the identity
// (PLUS's mark of a tool it cannot see). Prints "port N" on its first line (--port 0: any free
// port), and a summary line at the end. Exit status 1 when no client connected within --wait s.
#include <igtlClientSocket.h>
#include <igtlServerSocket.h>
#include <igtlTimeStamp.h>
#include <igtlTransformMessage.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

namespace {

struct Args {
  int port = 0;
  double rate_hz = 40.0;
  double duration_s = 60.0;
  double wait_s = 30.0;
  std::string tool = "CatheterTipToTracker";
  std::string other_tool;
  std::string sent_path = "sent.csv";
  bool resend = false;
  std::string replay_path;
};

struct ReplayRow {
  double t_s;
  float p[3];
  bool ok;
};

std::vector<ReplayRow> ReadReplay(const std::string& path) {
  std::vector<ReplayRow> rows;
  FILE* f = std::fopen(path.c_str(), "r");
  if (!f) return rows;
  char line[512];
  if (!std::fgets(line, sizeof line, f)) line[0] = 0;  // the header
  while (std::fgets(line, sizeof line, f)) {
    ReplayRow r{};
    char status[32] = {};
    if (std::sscanf(line, "%lf,%f,%f,%f,%31s", &r.t_s, &r.p[0], &r.p[1], &r.p[2], status) != 5)
      continue;
    r.ok = std::strcmp(status, "OK") == 0;
    rows.push_back(r);
  }
  std::fclose(f);
  return rows;
}

[[noreturn]] void Usage(const char* why) {
  std::fprintf(stderr,
               "plus_like_server: %s\nusage: plus_like_server [--port N] [--rate HZ] "
               "[--duration S] [--wait S] [--tool NAME] [--other-tool NAME] [--resend] "
               "[--sent FILE]\n",
               why);
  std::exit(2);
}

Args Parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) Usage(("missing value after " + k).c_str());
      return argv[++i];
    };
    if (k == "--port") {
      a.port = std::atoi(value().c_str());
    } else if (k == "--rate") {
      a.rate_hz = std::atof(value().c_str());
    } else if (k == "--duration") {
      a.duration_s = std::atof(value().c_str());
    } else if (k == "--wait") {
      a.wait_s = std::atof(value().c_str());
    } else if (k == "--tool") {
      a.tool = value();
    } else if (k == "--other-tool") {
      a.other_tool = value();
    } else if (k == "--sent") {
      a.sent_path = value();
    } else if (k == "--replay") {
      a.replay_path = value();
    } else if (k == "--resend") {
      a.resend = true;
    } else {
      Usage(("unknown argument " + k).c_str());
    }
  }
  if (!(a.rate_hz > 0 && a.rate_hz <= 1000) || !(a.duration_s > 0) || a.port < 0 ||
      a.port > 65535 || a.tool.empty() || a.tool.size() > 20)
    Usage("bad values");
  return a;
}

double WallS() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// The pose of the tool at sample n: a 1 Hz circle of 40 mm with a slow drift in z.
void PoseAt(long n, double rate_hz, igtl::Matrix4x4& m, float p[3]) {
  igtl::IdentityMatrix(m);
  const double a = 2 * M_PI * static_cast<double>(n) / rate_hz;
  p[0] = static_cast<float>(40.0 * std::cos(a));
  p[1] = static_cast<float>(40.0 * std::sin(a));
  p[2] = static_cast<float>(-150.0 + 0.01 * static_cast<double>(n));
  const float c = static_cast<float>(std::cos(0.1 * a)), s = static_cast<float>(std::sin(0.1 * a));
  m[0][0] = c;
  m[0][1] = -s;
  m[1][0] = s;
  m[1][1] = c;
  for (int k = 0; k < 3; ++k) m[k][3] = p[k];
}

// The timestamp as it is on the wire (header bytes 34..41, 32.32 fixed point, big endian).
double WireTimestampS(igtl::MessageBase* msg) {
  const auto* b = static_cast<const unsigned char*>(msg->GetPackPointer());
  std::uint64_t v = 0;
  for (int i = 34; i < 42; ++i) v = (v << 8) | b[i];
  return static_cast<double>(v >> 32) + static_cast<double>(v & 0xFFFFFFFFULL) / 4294967296.0;
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = Parse(argc, argv);
  std::signal(SIGPIPE, SIG_IGN);  // a vanished client is a failed send, not the end
  igtl::ServerSocket::Pointer server = igtl::ServerSocket::New();
  if (server->CreateServer(a.port) != 0) {
    std::fprintf(stderr, "plus_like_server: cannot listen on port %d\n", a.port);
    return 1;
  }
  std::printf("port %d\n", server->GetServerPort());
  std::fflush(stdout);
  FILE* sent = std::fopen(a.sent_path.c_str(), "w");
  if (!sent) {
    std::fprintf(stderr, "plus_like_server: cannot write %s\n", a.sent_path.c_str());
    return 1;
  }
  std::fprintf(sent, "t_s,x_mm,y_mm,z_mm\n");

  igtl::ClientSocket::Pointer client =
      server->WaitForConnection(static_cast<unsigned long>(a.wait_s * 1000));
  if (client.IsNull()) {
    std::fprintf(stderr, "plus_like_server: no client within %g s\n", a.wait_s);
    return 1;
  }
  long samples = 0, messages = 0, send_failures = 0, connections = 1, invalid = 0;
  igtl::TransformMessage::Pointer msg = igtl::TransformMessage::New();
  igtl::TransformMessage::Pointer other = igtl::TransformMessage::New();
  igtl::TimeStamp::Pointer ts = igtl::TimeStamp::New();
  const auto start = std::chrono::steady_clock::now();
  const std::vector<ReplayRow> replay =
      a.replay_path.empty() ? std::vector<ReplayRow>{} : ReadReplay(a.replay_path);
  if (!a.replay_path.empty() && replay.empty()) {
    std::fprintf(stderr, "plus_like_server: no rows in %s\n", a.replay_path.c_str());
    return 1;
  }
  const long total =
      replay.empty() ? std::lround(a.duration_s * a.rate_hz) : static_cast<long>(replay.size());
  for (long n = 0; n < total; ++n) {
    const double due_s = replay.empty() ? n / a.rate_hz : replay[n].t_s - replay[0].t_s;
    std::this_thread::sleep_until(start + std::chrono::duration<double>(due_s));
    if (client.IsNull() || !client->GetConnected()) {
      client = server->WaitForConnection(100);  // a client that left: wait for it again
      if (client.IsNull()) continue;            // this pose is not sent to anyone
      ++connections;
    }
    igtl::Matrix4x4 m;
    float p[3];
    PoseAt(n, a.rate_hz, m, p);
    if (!replay.empty()) {
      igtl::IdentityMatrix(m);
      for (int k = 0; k < 3; ++k) {
        p[k] = replay[n].ok ? replay[n].p[k] : 0.0f;
        m[k][3] = p[k];
      }
    }
    ts->SetTime(WallS());
    msg->SetDeviceName(a.tool.c_str());
    msg->SetMatrix(m);
    msg->SetTimeStamp(ts);
    msg->Pack();
    bool ok = true;
    if (!a.other_tool.empty()) {
      igtl::Matrix4x4 o;
      float q[3];
      PoseAt(n + 1000, a.rate_hz, o, q);
      other->SetDeviceName(a.other_tool.c_str());
      other->SetMatrix(o);
      other->SetTimeStamp(ts);
      other->Pack();
      ok = client->Send(other->GetPackPointer(), other->GetPackSize()) == 1;
      messages += ok;
    }
    for (int copy = 0; ok && copy < (a.resend ? 2 : 1); ++copy) {
      ok = client->Send(msg->GetPackPointer(), msg->GetPackSize()) == 1;
      messages += ok;
    }
    if (!ok) {
      ++send_failures;
      client->CloseSocket();
      client = nullptr;
      continue;
    }
    ++samples;
    std::fprintf(sent, "%.17g,%.9g,%.9g,%.9g\n", WireTimestampS(msg), p[0], p[1], p[2]);
    if (!replay.empty() && !replay[n].ok) ++invalid;
  }
  std::fclose(sent);
  std::printf(
      "sent %ld poses of %s (%ld as invalid, %ld messages) in %.2f s, %ld connection(s), %ld "
      "send failure(s)\n",
      samples, a.tool.c_str(), invalid, messages,
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), connections,
      send_failures);
  if (client.IsNotNull()) client->CloseSocket();
  return 0;
}
