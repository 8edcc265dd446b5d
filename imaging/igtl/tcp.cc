#include "imaging/igtl/tcp.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace echoservo::imaging::openigtlink::tcp {

Fd& Fd::operator=(Fd&& other) noexcept {
  if (this != &other) {
    reset();
    fd_ = other.release();
  }
  return *this;
}

void Fd::reset() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void SplitHostPort(const std::string& text, std::string& host, int& port) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size()) {
    throw std::invalid_argument("expected HOST:PORT, got '" + text + "'");
  }
  host = text.substr(0, colon);
  const std::string p = text.substr(colon + 1);
  std::size_t used = 0;
  int value = 0;
  try {
    value = std::stoi(p, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != p.size() || value < 1 || value > 65535) {
    throw std::invalid_argument("bad port in '" + text + "' (expected 1..65535)");
  }
  port = value;
}

Fd Listen(const std::string& bind_address, int port, int& bound_port) {
  Fd fd(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  if (!fd.valid()) throw std::runtime_error(std::string("socket: ") + std::strerror(errno));
  const int one = 1;
  ::setsockopt(fd.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  if (::inet_pton(AF_INET, bind_address.c_str(), &addr.sin_addr) != 1) {
    throw std::invalid_argument("bind address '" + bind_address + "' is not an IPv4 address");
  }
  if (::bind(fd.get(), reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    throw std::runtime_error("bind " + bind_address + ":" + std::to_string(port) + ": " +
                             std::strerror(errno));
  }
  if (::listen(fd.get(), 8) != 0)
    throw std::runtime_error(std::string("listen: ") + std::strerror(errno));
  socklen_t len = sizeof addr;
  ::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&addr), &len);
  bound_port = ntohs(addr.sin_port);
  return fd;
}

Fd Accept(const Fd& listener, int timeout_ms) {
  pollfd p{listener.get(), POLLIN, 0};
  if (::poll(&p, 1, timeout_ms) <= 0) return Fd();
  return Fd(::accept4(listener.get(), nullptr, nullptr, SOCK_CLOEXEC));
}

std::string DescribeErrno(int error_number) {
  std::string text = std::strerror(error_number);
  if (!text.empty() && text[0] >= 'A' && text[0] <= 'Z' &&
      (text.size() < 2 || !(text[1] >= 'A' && text[1] <= 'Z')))
    text[0] = static_cast<char>(text[0] - 'A' + 'a');  // "Connection refused", not "I/O error"
  const char* name = ::strerrorname_np(error_number);
  return name ? text + " (" + name + ")" : text;
}

Fd Connect(const std::string& host, int port, int timeout_ms, std::string& error) {
  int error_number = 0;
  Fd fd = Connect(host, port, timeout_ms, error, error_number);
  if (!fd.valid() && error_number != 0)
    error = "connect " + host + ":" + std::to_string(port) + ": " + error;
  return fd;
}

Fd Connect(const std::string& host, int port, int timeout_ms, std::string& error,
           int& error_number) {
  error_number = 0;
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  const int rc = ::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &res);
  if (rc != 0 || res == nullptr) {
    error = "resolve " + host + ": " + ::gai_strerror(rc);
    return Fd();
  }
  Fd fd(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
  int result = fd.valid() ? ::connect(fd.get(), res->ai_addr, res->ai_addrlen) : -1;
  int err = errno;
  ::freeaddrinfo(res);
  if (!fd.valid()) {
    error_number = err;
    error = "socket: " + DescribeErrno(err);
    return Fd();
  }
  if (result != 0 && err == EINPROGRESS) {
    pollfd p{fd.get(), POLLOUT, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) {
      error_number = ETIMEDOUT;
      error = "no answer within " + std::to_string(timeout_ms) + " ms (ETIMEDOUT)";
      return Fd();
    }
    int soerr = 0;
    socklen_t len = sizeof soerr;
    ::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &soerr, &len);
    result = soerr == 0 ? 0 : -1;
    err = soerr;
  }
  if (result != 0) {
    error_number = err;
    error = DescribeErrno(err);
    return Fd();
  }
  const int flags = ::fcntl(fd.get(), F_GETFL);
  ::fcntl(fd.get(), F_SETFL, flags & ~O_NONBLOCK);
  SetNoDelay(fd.get());
  return fd;
}

IoResult ReadExact(int fd, void* data, std::size_t n, int idle_timeout_ms, std::size_t& got) {
  got = 0;
  auto* p = static_cast<std::uint8_t*>(data);
  while (got < n) {
    pollfd pf{fd, POLLIN, 0};
    const int ready = ::poll(&pf, 1, idle_timeout_ms);
    if (ready == 0) return IoResult::kTimeout;
    if (ready < 0) {
      if (errno == EINTR) continue;
      return IoResult::kError;
    }
    const ssize_t r = ::recv(fd, p + got, n - got, 0);
    if (r == 0) return IoResult::kClosed;
    if (r < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      return errno == ECONNRESET ? IoResult::kClosed : IoResult::kError;
    }
    got += static_cast<std::size_t>(r);
  }
  return IoResult::kOk;
}

IoResult WriteAll(int fd, const void* data, std::size_t n, int timeout_ms) {
  const auto* p = static_cast<const std::uint8_t*>(data);
  std::size_t sent = 0;
  while (sent < n) {
    pollfd pf{fd, POLLOUT, 0};
    const int ready = ::poll(&pf, 1, timeout_ms);
    if (ready == 0) return IoResult::kTimeout;
    if (ready < 0) {
      if (errno == EINTR) continue;
      return IoResult::kError;
    }
    if (pf.revents & (POLLERR | POLLHUP)) return IoResult::kClosed;
    const ssize_t w = ::send(fd, p + sent, n - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (w < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      return (errno == EPIPE || errno == ECONNRESET) ? IoResult::kClosed : IoResult::kError;
    }
    sent += static_cast<std::size_t>(w);
  }
  return IoResult::kOk;
}

void SetNoDelay(int fd) {
  const int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
}

void SetBuffers(int fd, int bytes) {
  ::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &bytes, sizeof bytes);
  ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &bytes, sizeof bytes);
}

}  // namespace echoservo::imaging::openigtlink::tcp
