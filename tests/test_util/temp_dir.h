// A scratch folder for one test: under the system temp dir, named after the process and
// the running test (so parallel ctest processes never share it), removed on destruction.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <system_error>

namespace echoservo::testing {

class TempDir {
 public:
  // The folder echoservo_<tag>_<pid>_<test name>; any leftover from an earlier run is
  // removed. It is left for the test to create unless `create` is set.
  explicit TempDir(const std::string& tag, bool create = false) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = info != nullptr ? info->name() : "suite";
    std::replace(name.begin(), name.end(), '/', '_');  // parameterised test names
    path_ = std::filesystem::temp_directory_path() /
            ("echoservo_" + tag + "_" + std::to_string(::getpid()) + "_" + name);
    std::filesystem::remove_all(path_);
    if (create) std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::string str() const { return path_.string(); }

 private:
  std::filesystem::path path_;
};

}  // namespace echoservo::testing
