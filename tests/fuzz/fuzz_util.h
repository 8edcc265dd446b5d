// Shared helpers of the libFuzzer targets (tests/fuzz/fuzz_*.cc, docs/reliability.md).
//
// The readers under test take file paths (they check sizes against the file before
// allocating), so each input is written to a scratch file first: one per process and
// extension under $TMPDIR (default /tmp), named by the process id so that parallel fuzzing
// jobs (-jobs/-workers) do not collide, removed at exit.
//
// Contract checked by every target: a reader may reject an input only with the exception
// its header documents (std::invalid_argument and its subclasses, MessageError for
// OpenIGTLink); anything else escaping — another exception type, a crash, a sanitizer
// report — is a finding.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <span>
#include <stdexcept>
#include <string>

namespace echoservo::fuzz {

class ScratchFiles {
 public:
  ~ScratchFiles() {
    std::error_code ec;
    for (const auto& [ext, path] : paths_) std::filesystem::remove(path, ec);
  }
  // Writes `bytes` to this process's scratch file ending in `ext` (e.g. ".igs.mha").
  const std::filesystem::path& Write(const std::string& ext, std::span<const std::uint8_t> bytes) {
    auto it = paths_.find(ext);
    if (it == paths_.end()) {
      const char* tmp = std::getenv("TMPDIR");
      const std::filesystem::path dir = (tmp && *tmp) ? tmp : "/tmp";
      it = paths_.emplace(ext, dir / ("echoservo_fuzz_" + std::to_string(::getpid()) + ext)).first;
    }
    std::ofstream out(it->second, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) throw std::runtime_error("fuzz: cannot write " + it->second.string());
    return it->second;
  }

 private:
  std::map<std::string, std::filesystem::path> paths_;
};

inline ScratchFiles& Scratch() {
  static ScratchFiles files;
  return files;
}

}  // namespace echoservo::fuzz
