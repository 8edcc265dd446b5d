#include "formats/durable_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

namespace echoservo::formats {
namespace fs = std::filesystem;

namespace {

[[noreturn]] void FailErrno(const fs::path& path, const char* what) {
  throw std::runtime_error(path.string() + ": " + what + ": " + std::strerror(errno));
}

int OpenForWriting(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) FailErrno(path, "cannot open for writing");
  return fd;
}

void WriteAll(int fd, const void* data, std::size_t size, const fs::path& path) {
  const char* bytes = static_cast<const char*>(data);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, bytes + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) FailErrno(path, "write error");
    done += static_cast<std::size_t>(n);
  }
}

}  // namespace

AppendOnlyFile::AppendOnlyFile(const fs::path& path) : fd_(OpenForWriting(path)), path_(path) {}

AppendOnlyFile::~AppendOnlyFile() {
  if (fd_ >= 0) ::close(fd_);
}

AppendOnlyFile::AppendOnlyFile(AppendOnlyFile&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), path_(std::move(other.path_)) {}

AppendOnlyFile& AppendOnlyFile::operator=(AppendOnlyFile&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    path_ = std::move(other.path_);
  }
  return *this;
}

void AppendOnlyFile::Append(const void* data, std::size_t size) {
  if (fd_ < 0) throw std::logic_error("AppendOnlyFile::Append on a closed file");
  WriteAll(fd_, data, size, path_);
}

void AppendOnlyFile::SyncData() {
  if (fd_ >= 0 && ::fdatasync(fd_) != 0) FailErrno(path_, "cannot sync to disk");
}

void ReplaceFileContents(const fs::path& path, std::string_view text) {
  fs::path tmp = path;
  tmp += ".tmp";
  const int fd = OpenForWriting(tmp);
  try {
    WriteAll(fd, text.data(), text.size(), tmp);
  } catch (...) {
    ::close(fd);
    throw;
  }
  if (::close(fd) != 0) FailErrno(tmp, "close failed");
  if (std::rename(tmp.c_str(), path.c_str()) != 0) FailErrno(path, "cannot replace");
}

}  // namespace echoservo::formats
