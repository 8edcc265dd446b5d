// A RUN directory (formats/run_record.h) that a command is about to write: if the command
// fails before it calls Keep(), the guard's destructor removes what this process created
// there, so the same command can be run again with the same --out (a half-written RUN with
// its run.json would make the retry fail with "run.json exists"). What was there before is
// left alone: a folder that did not exist is removed whole (with the parents it needed),
// in a folder that existed only the entries that were not there at construction are.
#pragma once

#include <filesystem>
#include <set>
#include <system_error>
#include <utility>

namespace echoservo::formats {

class RunDirGuard {
 public:
  // An empty `dir` guards nothing.
  explicit RunDirGuard(std::filesystem::path dir) : dir_(std::move(dir)) {
    namespace fs = std::filesystem;
    if (dir_.empty()) return;
    std::error_code ec;
    if (fs::is_directory(dir_, ec)) {
      for (fs::directory_iterator it(dir_, ec), end; !ec && it != end; it.increment(ec))
        before_.insert(it->path().filename());
      existed_ = true;
      return;
    }
    if (fs::exists(dir_, ec) || ec) return;  // not a folder: the writer's error, nothing ours
    // The topmost missing folder on the way to `dir`: removing it removes all we create.
    fs::path p = fs::absolute(dir_, ec).lexically_normal();
    if (ec) return;
    if (p.filename().empty()) p = p.parent_path();
    while (!p.parent_path().empty() && p.parent_path() != p && !fs::exists(p.parent_path(), ec))
      p = p.parent_path();
    created_root_ = p;
  }
  ~RunDirGuard() {
    if (kept_ || dir_.empty()) return;
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!existed_) {
      if (!created_root_.empty()) fs::remove_all(created_root_, ec);
      return;
    }
    std::set<fs::path> added;
    for (fs::directory_iterator it(dir_, ec), end; !ec && it != end; it.increment(ec))
      if (before_.count(it->path().filename()) == 0) added.insert(it->path());
    for (const fs::path& p : added) fs::remove_all(p, ec);
  }
  RunDirGuard(const RunDirGuard&) = delete;
  RunDirGuard& operator=(const RunDirGuard&) = delete;

  // The run succeeded (or stopped cleanly): what was written stays.
  void Keep() { kept_ = true; }

 private:
  std::filesystem::path dir_;
  std::filesystem::path created_root_;  // removed on failure when the folder was new
  std::set<std::filesystem::path> before_;
  bool existed_ = false;
  bool kept_ = false;
};

}  // namespace echoservo::formats
