// File writes that survive the writing process being killed (kill -9, a crash): what a call
// has returned from is in the kernel, whole, and no reader ever sees a half-replaced file.
// Power loss is a different matter: SyncData (fdatasync) is what makes data durable across
// it. Used by the run recorder (formats/run_record.h) and the volume recorder
// (imaging/io/sequence_writer.h). Errors: std::runtime_error naming the file and errno's text.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string_view>

namespace echoservo::formats {

// An append-only file descriptor. Append hands its bytes to the kernel in one write(2)
// where the kernel allows (a regular file takes it whole), retrying after signals and
// short writes; there is no user-space buffer to lose.
class AppendOnlyFile {
 public:
  AppendOnlyFile() = default;
  // Creates `path` (truncating an existing file).
  explicit AppendOnlyFile(const std::filesystem::path& path);
  ~AppendOnlyFile();
  AppendOnlyFile(AppendOnlyFile&& other) noexcept;
  AppendOnlyFile& operator=(AppendOnlyFile&& other) noexcept;
  AppendOnlyFile(const AppendOnlyFile&) = delete;
  AppendOnlyFile& operator=(const AppendOnlyFile&) = delete;

  bool is_open() const { return fd_ >= 0; }
  const std::filesystem::path& path() const { return path_; }
  void Append(const void* data, std::size_t size);
  void Append(std::string_view text) { Append(text.data(), text.size()); }
  // fdatasync: the data reach the disk (survives power loss, not only a process kill).
  void SyncData();

 private:
  int fd_ = -1;
  std::filesystem::path path_;
};

// Writes `text` to `<path>.tmp` and renames it over `path`: a reader (or the file after a
// kill) has the old content or the new, never a mix or a truncated file.
void ReplaceFileContents(const std::filesystem::path& path, std::string_view text);

}  // namespace echoservo::formats
