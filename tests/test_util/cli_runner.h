// Runs the echoservo binary (ECHOSERVO_CLI, defined by echoservo_test()) or any shell
// command line as a user would, for the end-to-end tests: stdout captured, stderr through
// a temporary file, and the exit code.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>

namespace echoservo::testing {

struct RunResult {
  int rc = -1;      // exit status; -1 if the command could not run or did not exit
  std::string out;  // stdout
  std::string err;  // stderr
};

// The whole file (binary), or empty if it cannot be read.
inline std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Single-quotes `s` for /bin/sh.
inline std::string ShellQuote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// Runs a shell command line; its stderr (the last command's, for a list) goes through a
// temporary file unique to this process and call.
inline RunResult RunShell(const std::string& command) {
  static std::atomic<int> counter{0};
  const std::filesystem::path err_path =
      std::filesystem::temp_directory_path() / ("echoservo_run_err_" + std::to_string(::getpid()) +
                                                "_" + std::to_string(counter++) + ".txt");
  RunResult r;
  FILE* pipe = ::popen((command + " 2>" + ShellQuote(err_path.string())).c_str(), "r");
  if (pipe == nullptr) return r;
  std::array<char, 4096> buf{};
  std::size_t n = 0;
  while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) r.out.append(buf.data(), n);
  const int status = ::pclose(pipe);
  r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.err = ReadFile(err_path);
  std::error_code ec;
  std::filesystem::remove(err_path, ec);
  return r;
}

// Runs `echoservo ARGS` (ARGS as a shell would split them), in `cwd` if given.
inline RunResult RunCli(const std::string& args, const std::filesystem::path& cwd = {}) {
  const std::string cli = std::string(ECHOSERVO_CLI) + " " + args;
  return RunShell(cwd.empty() ? cli : "cd " + ShellQuote(cwd.string()) + " && " + cli);
}

// Whether this build has the echoservo program: the sanitizer build leaves it out unless
// ECHOSERVO_SANITIZE_CLI is ON (tests/CMakeLists.txt).
#if defined(ECHOSERVO_CLI_BUILT) && !ECHOSERVO_CLI_BUILT
inline constexpr bool kCliBuilt = false;
#else
inline constexpr bool kCliBuilt = true;
#endif

}  // namespace echoservo::testing

// Skips the current test where the echoservo program is not built, saying why. For the
// tests of a library suite that also run the program; suites that only drive the program
// are not built there at all (echoservo_test CLI / NEEDS_CLI).
#define ECHOSERVO_REQUIRES_CLI()                                                            \
  do {                                                                                      \
    if (!::echoservo::testing::kCliBuilt)                                                   \
      GTEST_SKIP() << "runs the echoservo program, which this build leaves out (sanitizer " \
                      "stage without ECHOSERVO_SANITIZE_CLI; the Release suite runs it)";   \
  } while (0)
