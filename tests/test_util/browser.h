// Checks of the self-contained HTML reports (`lab report`, `report`): the page loads
// nothing from outside, and headless Chromium renders it without a script error or a
// console message. Chromium is required (scripts/setup.sh installs it): tests that need
// it FAIL when it is not on PATH, they do not skip.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "tests/test_util/cli_runner.h"

namespace echoservo::testing::browser {

namespace fs = std::filesystem;

inline std::size_t Count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t p = text.find(what); p != std::string::npos;
       p = text.find(what, p + what.size()))
    ++n;
  return n;
}

// The executable `program` on PATH, or empty.
inline fs::path FindOnPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) continue;
    const fs::path candidate = fs::path(dir) / program;
    if (fs::is_regular_file(candidate) && ::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return {};
}

constexpr const char* kNoChromium =
    "chromium is not on PATH: the HTML report must be checked in a real browser. Install it "
    "(`apt-get install -y chromium`; scripts/setup.sh installs it) and rerun.";

// Runs headless Chromium on `html` with a fresh profile under `work`; `mode` is the
// output option (--screenshot=... or --dump-dom). Returns the run with Chromium's log.
inline RunResult RunChromium(const fs::path& chromium, const fs::path& html, const fs::path& work,
                             const std::string& mode) {
  const fs::path profile = work / ("profile_" + std::to_string(::getpid()));
  fs::remove_all(profile);
  fs::create_directories(profile);
  const std::string cmd =
      "timeout 120 " + ShellQuote(chromium.string()) +
      " --headless --no-sandbox --disable-gpu --disable-quic --no-first-run"
      " --disable-background-networking --disable-component-update --disable-sync"
      " --user-data-dir=" +
      ShellQuote(profile.string()) + " " + mode +
      " --window-size=1280,2000 --enable-logging=stderr --v=0 " +
      ShellQuote("file://" + fs::absolute(html).string());
  RunResult r = RunShell(cmd);
  fs::remove_all(profile);
  return r;
}

// Lines of Chromium's log that report a script error or any console message. This
// Chromium logs every console level as "INFO:CONSOLE:<line>]" (older ones as
// "CONSOLE(<line>)"), so console.error cannot be told apart by level; the report logs
// nothing, so any console line is a failure, as is any uncaught exception.
inline std::vector<std::string> ScriptProblems(const std::string& log) {
  std::vector<std::string> problems;
  std::stringstream lines(log);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.find("Uncaught") != std::string::npos || line.find("CONSOLE") != std::string::npos) {
      problems.push_back(line);
    }
  }
  return problems;
}

// Values of every `attr=` in `html` (quoted or not), lower-cased.
inline std::vector<std::string> AttributeValues(const std::string& html, const std::string& attr) {
  std::vector<std::string> values;
  std::string lower = html;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  for (std::size_t p = lower.find(attr); p != std::string::npos; p = lower.find(attr, p + 1)) {
    std::size_t v = p + attr.size();
    while (v < lower.size() && (lower[v] == ' ' || lower[v] == '"' || lower[v] == '\'')) ++v;
    values.push_back(lower.substr(v, 12));
  }
  return values;
}

inline bool IsExternal(const std::string& value) {
  return value.rfind("http:", 0) == 0 || value.rfind("https:", 0) == 0 ||
         value.rfind("//", 0) == 0 || value.rfind("ftp:", 0) == 0;
}

// One HTML5 page with inline styles and scripts and no external reference.
inline void ExpectSelfContainedPage(const std::string& html) {
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(Count(html, "<html"), 1u);
  EXPECT_EQ(Count(html, "</html>"), 1u);
  EXPECT_NE(html.find("<meta charset=\"utf-8\">"), std::string::npos);
  for (const char* attr : {"src=", "href=", "url(", "@import", "action=", "srcset="}) {
    for (const std::string& v : AttributeValues(html, attr))
      EXPECT_FALSE(IsExternal(v)) << attr << v;
  }
  EXPECT_EQ(html.find("http://"), std::string::npos);
  EXPECT_EQ(html.find("https://"), std::string::npos);
  EXPECT_EQ(html.find("<link rel=\"stylesheet\""), std::string::npos);
  EXPECT_EQ(html.find("<iframe"), std::string::npos);
  EXPECT_EQ(Count(html, "<script"), Count(html, "<script>")) << "every script must be inline";
  EXPECT_NE(html.find("<style>"), std::string::npos);
}

}  // namespace echoservo::testing::browser
