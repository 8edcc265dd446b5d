// Artefacts that several tests of one executable read, made once per ctest run.
// echoservo_test(NAME FIXTURE Suite ...) registers the executable's `SuiteSetup.*` tests
// as a CTest fixture (FIXTURES_SETUP) that the `Suite.*` tests require, and gives both
// ECHOSERVO_TEST_FIXTURE_DIR, a folder in the build tree. The setup test writes its
// artefacts and command results there and marks the folder complete; the suite reads
// them. Run outside ctest (no variable), the suite makes its own artefacts.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

#include "tests/test_util/cli_runner.h"

namespace echoservo::testing {

// The fixture folder ctest names, or nothing outside ctest.
inline std::optional<std::filesystem::path> SharedFixtureDir() {
  const char* dir = std::getenv("ECHOSERVO_TEST_FIXTURE_DIR");
  if (dir == nullptr || *dir == '\0') return std::nullopt;
  return std::filesystem::path(dir);
}

// Saves a command's result as NAME.rc, NAME.out and NAME.err in `dir`.
inline void SaveResult(const std::filesystem::path& dir, const std::string& name,
                       const RunResult& r) {
  std::ofstream(dir / (name + ".rc")) << r.rc;
  std::ofstream(dir / (name + ".out"), std::ios::binary) << r.out;
  std::ofstream(dir / (name + ".err"), std::ios::binary) << r.err;
}

// The result SaveResult wrote; rc −1 and a message in `err` when it is missing.
inline RunResult LoadResult(const std::filesystem::path& dir, const std::string& name) {
  RunResult r;
  std::ifstream rc(dir / (name + ".rc"));
  if (!(rc >> r.rc)) {
    r.rc = -1;
    r.err = "no result " + name + " in the shared fixture " + dir.string();
    return r;
  }
  r.out = ReadFile(dir / (name + ".out"));
  r.err = ReadFile(dir / (name + ".err"));
  return r;
}

// The setup test calls this last: readers accept only a complete folder.
inline void MarkFixtureComplete(const std::filesystem::path& dir) {
  std::ofstream(dir / "COMPLETE") << "ok\n";
}

inline bool FixtureComplete(const std::filesystem::path& dir) {
  return std::filesystem::is_regular_file(dir / "COMPLETE");
}

}  // namespace echoservo::testing
