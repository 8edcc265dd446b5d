// Minimal POSIX TCP helpers for the OpenIGTLink server and ingest client (internal to
// imaging/igtl). Plain sockets rather than igtl::Socket: we need poll()-based timeouts so
// that threads stop promptly, MSG_NOSIGNAL on send, and partial-read accounting to tell a
// connection dropped mid-message from a clean close. All calls are bounded by timeouts.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace echoservo::imaging::openigtlink::tcp {

// An owned file descriptor (closed on destruction).
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  Fd(Fd&& other) noexcept : fd_(other.release()) {}
  Fd& operator=(Fd&& other) noexcept;
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() { reset(); }
  int get() const { return fd_; }
  bool valid() const { return fd_ >= 0; }
  int release() {
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }
  void reset();

 private:
  int fd_ = -1;
};

// Splits "HOST:PORT"; throws std::invalid_argument when malformed.
void SplitHostPort(const std::string& text, std::string& host, int& port);

// A listening socket on `bind_address:port` (port 0: ephemeral). Throws std::runtime_error.
Fd Listen(const std::string& bind_address, int port, int& bound_port);
// Accepts one connection if one arrives within timeout_ms; invalid Fd otherwise.
Fd Accept(const Fd& listener, int timeout_ms);
// Connects within timeout_ms; invalid Fd on failure (error text in `error`).
Fd Connect(const std::string& host, int port, int timeout_ms, std::string& error);
// The same; `error_number` gets the failure's errno (ETIMEDOUT past timeout_ms; 0 for a
// failure without one, such as a host name that does not resolve) and `error` a text
// without the address: "connection refused (ECONNREFUSED)", "resolve HOST: ...".
Fd Connect(const std::string& host, int port, int timeout_ms, std::string& error,
           int& error_number);
// "connection refused (ECONNREFUSED)": strerror in lower case and the errno's name.
std::string DescribeErrno(int error_number);

enum class IoResult { kOk, kTimeout, kClosed, kError };
// Reads exactly n bytes unless the peer closes, an error occurs, or no byte arrives for
// idle_timeout_ms; `got` says how many were read.
IoResult ReadExact(int fd, void* data, std::size_t n, int idle_timeout_ms, std::size_t& got);
// Writes all n bytes (MSG_NOSIGNAL) unless the peer stalls for timeout_ms or fails.
IoResult WriteAll(int fd, const void* data, std::size_t n, int timeout_ms);

void SetNoDelay(int fd);
void SetBuffers(int fd, int bytes);

}  // namespace echoservo::imaging::openigtlink::tcp
