// End-to-end test of `echoservo lab report`: a small dataset is recorded with the CLI
// (in a folder whose name and one trial name need HTML escaping), the report is written
// and checked to be one self-contained HTML page (no external resource, inline SVG with
// at most 2000 points per line, the error ladder, every candidate effect, the verdict,
// escaped names), then rendered in headless Chromium, which must load it without a script
// error or console message. Chromium is required (scripts/setup.sh installs it): when it
// is not on PATH the browser tests FAIL, they do not skip.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "hw/effect_registry.h"
#include "report/svg_plot.h"
#include "tests/test_util/browser.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/shared_fixture.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;

using Result = echoservo::testing::RunResult;
using echoservo::testing::FixtureComplete;
using echoservo::testing::LoadResult;
using echoservo::testing::MarkFixtureComplete;
using echoservo::testing::ReadFile;
using echoservo::testing::RunCli;
using echoservo::testing::RunShell;
using echoservo::testing::SaveResult;
using echoservo::testing::SharedFixtureDir;
using echoservo::testing::ShellQuote;
using echoservo::testing::browser::Count;
using echoservo::testing::browser::ExpectSelfContainedPage;
using echoservo::testing::browser::FindOnPath;
using echoservo::testing::browser::kNoChromium;
using echoservo::testing::browser::RunChromium;
using echoservo::testing::browser::ScriptProblems;

struct Page {
  fs::path work;  // the dataset and the report
  fs::path dataset;
  fs::path html_path;
  Result record;
  Result report;
  std::string html;
};

constexpr const char* kOddTrialName = "trial_odd <b>&\"'name";

Page PageIn(const fs::path& work) {
  Page page;
  page.work = work;
  page.dataset = work / "bench & <runs>";
  page.html_path = work / "report.html";
  return page;
}

// Records the small dataset (one trial renamed so that its name needs escaping) and writes
// its report, in `work`.
Page MakePage(const fs::path& work) {
  Page page = PageIn(work);
  fs::remove_all(work);
  fs::create_directories(work);
  page.record = RunCli("sim record --out " + ShellQuote(page.dataset.string()) +
                       " --configs lab --trajectories sine:4:0.8 --duration 3 --effects "
                       "seed+capstan_friction --seed 7");
  if (page.record.rc != 0) return page;
  std::vector<fs::path> csvs;
  for (const auto& e : fs::directory_iterator(page.dataset)) {
    if (e.path().extension() == ".csv") csvs.push_back(e.path());
  }
  std::sort(csvs.begin(), csvs.end());
  if (!csvs.empty()) {
    fs::path json = csvs.back();
    json.replace_extension(".json");
    fs::rename(csvs.back(), page.dataset / (std::string(kOddTrialName) + ".csv"));
    fs::rename(json, page.dataset / (std::string(kOddTrialName) + ".json"));
  }
  page.report = RunCli("lab report " + ShellQuote(page.dataset.string()) + " --model seed --out " +
                       ShellQuote(page.html_path.string()) + " --max-rounds 2 --json");
  page.html = ReadFile(page.html_path);
  return page;
}

// The shared fixture (tests/test_util/shared_fixture.h): under ctest the page is made
// once, here, and the LabReport tests read it.
TEST(LabReportSetup, RecordsADatasetAndWritesItsReport) {
  const auto shared = SharedFixtureDir();
  const fs::path work = shared ? *shared
                               : fs::temp_directory_path() /
                                     ("echoservo_lab_report_setup_" + std::to_string(::getpid()));
  const Page page = MakePage(work);
  EXPECT_EQ(page.record.rc, 0) << page.record.err;
  EXPECT_EQ(page.report.rc, 0) << page.report.err;
  EXPECT_FALSE(page.html.empty()) << "no report at " << page.html_path;
  if (!shared) {
    fs::remove_all(work);
  } else if (!::testing::Test::HasFailure()) {
    SaveResult(work, "record", page.record);
    SaveResult(work, "report", page.report);
    MarkFixtureComplete(work);
  }
}

class LabReport : public ::testing::Test {
 protected:
  // The shared page when ctest made it; otherwise (the binary run alone) one of its own.
  static void SetUpTestSuite() {
    scratch_ = new fs::path(fs::temp_directory_path() /
                            ("echoservo_lab_report_" + std::to_string(::getpid())));
    fs::remove_all(*scratch_);
    fs::create_directories(*scratch_);
    const auto shared = SharedFixtureDir();
    if (shared && FixtureComplete(*shared)) {
      page_ = new Page(PageIn(*shared));
      page_->record = LoadResult(*shared, "record");
      page_->report = LoadResult(*shared, "report");
      page_->html = ReadFile(page_->html_path);
    } else {
      page_ = new Page(MakePage(*scratch_ / "page"));
    }
  }
  static void TearDownTestSuite() {
    fs::remove_all(*scratch_);
    delete scratch_;
    delete page_;
    scratch_ = nullptr;
    page_ = nullptr;
  }
  void SetUp() override {
    ASSERT_EQ(page_->record.rc, 0) << page_->record.err;
    ASSERT_EQ(page_->report.rc, 0) << page_->report.err;
    ASSERT_FALSE(page_->html.empty()) << "no report at " << page_->html_path;
  }
  static inline Page* page_ = nullptr;
  static inline fs::path* scratch_ = nullptr;  // this process's own files (browser, shots)
};

TEST_F(LabReport, IsOneSelfContainedHtmlPage) {
  const std::string& html = page_->html;
  ExpectSelfContainedPage(html);
  EXPECT_GE(Count(html, "<svg"), 20u);
  EXPECT_EQ(Count(html, "<svg"), Count(html, "</svg>"));
}

TEST_F(LabReport, PlotsAtMost2000PointsPerLine) {
  const std::string& html = page_->html;
  std::size_t lines = 0, longest = 0;
  for (std::size_t p = html.find("points=\""); p != std::string::npos;
       p = html.find("points=\"", p + 1)) {
    const std::size_t end = html.find('"', p + 8);
    ASSERT_NE(end, std::string::npos);
    const std::size_t points = Count(html.substr(p + 8, end - p - 8), " ") + 1;
    longest = std::max(longest, points);
    ++lines;
  }
  EXPECT_GT(lines, 40u);
  EXPECT_LE(longest, report::svg::kMaxPointsPerLine);
  EXPECT_GE(longest, 1000u) << "3 s trials at 1 kHz: long lines are downsampled, not dropped";
}

TEST_F(LabReport, HasHeaderLadderDiagnosisParametersAndPlots) {
  const std::string& html = page_->html;
  const auto summary = nlohmann::json::parse(page_->report.out);
  const auto ladder = summary.at("ladder").get<std::vector<std::string>>();
  ASSERT_FALSE(ladder.empty());
  EXPECT_EQ(ladder.front(), "seed");
  EXPECT_LE(ladder.size(), 3u);  // --max-rounds 2
  for (const char* id : {"ladder", "diagnosis", "where", "parameters", "trials", "breakdown"}) {
    EXPECT_NE(html.find(std::string("<section id=\"") + id + "\">"), std::string::npos) << id;
  }
  // Where the seed fails: the hidden capstan friction leaves a force excess, so the table
  // ranks force variables and the residual is plotted against the top ones.
  EXPECT_NE(html.find("gain (noise var)"), std::string::npos);
  EXPECT_NE(html.find("force residual along "), std::string::npos);
  // Header: trial count, noise, the model.
  EXPECT_NE(html.find("<dt>Trials</dt><dd>8"), std::string::npos);
  EXPECT_NE(html.find("Estimated noise"), std::string::npos);
  EXPECT_NE(html.find("coulomb_friction, viscous_friction, backlash"), std::string::npos);
  // Ladder: every model visited, and the effect added at each step.
  EXPECT_NE(html.find("Error ladder"), std::string::npos);
  EXPECT_NE(html.find("effect added"), std::string::npos);
  auto tokens = [](const std::string& spec) {
    std::vector<std::string> out;
    std::stringstream ss(spec);
    for (std::string t; std::getline(ss, t, '+');) out.push_back(t);
    return out;
  };
  for (std::size_t i = 0; i < ladder.size(); ++i) {
    EXPECT_NE(html.find("<code>" + ladder[i] + "</code>"), std::string::npos) << ladder[i];
    if (i == 0) continue;
    const auto before = tokens(ladder[i - 1]);
    for (const std::string& t : tokens(ladder[i])) {
      if (std::find(before.begin(), before.end(), t) == before.end()) {
        EXPECT_NE(html.find("<td class=\"l\">+" + t + "</td>"), std::string::npos)
            << "effect added: " << t;
      }
    }
  }
  EXPECT_NE(html.find(summary.at("adequate").get<bool>() ? "Adequate:" : "Not adequate:"),
            std::string::npos);
  // Diagnosis of SPEC: every catalog effect not in the seed is a candidate, with evidence.
  const hw::EffectRegistry catalog = hw::EffectRegistry::WithBuiltinEffects();
  for (const std::string& e : catalog.Names()) {
    if (std::find(hw::SeedEffects().begin(), hw::SeedEffects().end(), e) != hw::SeedEffects().end())
      continue;
    EXPECT_GE(Count(html, "+" + e), 2u) << e;  // candidate table and evidence
  }
  EXPECT_NE(html.find("held-out tip excess explained"), std::string::npos);
  EXPECT_TRUE(html.find("ADEQUATE:") != std::string::npos ||
              html.find("MISSING EFFECT:") != std::string::npos ||
              html.find("UNEXPLAINED:") != std::string::npos);
  // The final model's summary (after its "adequate: "/"missing effect: " prefix), escaped.
  const std::string verdict = summary.at("summary").get<std::string>();
  const std::string tail = verdict.substr(verdict.find(": ") + 3);
  EXPECT_NE(html.find(report::svg::EscapeHtml(tail)), std::string::npos) << tail;
  // Parameters with SDs of SPEC and of the final model.
  EXPECT_NE(html.find("coulomb_friction.f0_n"), std::string::npos);
  EXPECT_NE(html.find("<th>SD</th>"), std::string::npos);
  if (ladder.size() > 1) {
    EXPECT_NE(html.find("Final model <code>" + ladder.back() + "</code>"), std::string::npos);
  }
  // Plots: 4 trials by default, with a selector; breakdowns by speed, configuration, phase.
  EXPECT_EQ(Count(html, "class=\"trial-panel\""), 4u);
  EXPECT_NE(html.find("id=\"trial-select\""), std::string::npos);
  for (const char* title :
       {"Tip position", "Force", "Tip residual", "Force residual", "Hysteresis: tip vs base",
        "Tip RMS by base speed", "Tip RMS by gap", "Tip RMS by total bend angle",
        "Force RMS by tip load", "Tip RMS by phase of motion", "Tip RMS along the ladder",
        "Force RMS along the ladder"}) {
    EXPECT_NE(html.find(std::string("aria-label=\"") + title), std::string::npos) << title;
  }
  for (const char* axis : {"time (s)", "tip RMS (mm)", "force RMS (N)", "base position (mm)"}) {
    EXPECT_NE(html.find(std::string(">") + axis + "<"), std::string::npos) << axis;
  }
}

TEST_F(LabReport, EscapesTrialNamesAndPaths) {
  std::string html = page_->html;  // without the line-break hints in long names
  for (std::size_t p = html.find("<wbr>"); p != std::string::npos; p = html.find("<wbr>", p))
    html.erase(p, 5);
  EXPECT_NE(html.find("trial_odd &lt;b&gt;&amp;&quot;&#39;name"), std::string::npos);
  EXPECT_EQ(html.find(kOddTrialName), std::string::npos);
  EXPECT_EQ(html.find("<b>&"), std::string::npos);
  EXPECT_NE(html.find("bench &amp; &lt;runs&gt;"), std::string::npos);
  EXPECT_EQ(html.find("<runs>"), std::string::npos);
}

TEST_F(LabReport, RendersInHeadlessChromiumWithoutScriptErrors) {
  const fs::path chromium = FindOnPath("chromium");
  ASSERT_FALSE(chromium.empty()) << kNoChromium;
  const fs::path shot = *scratch_ / "shot.png";
  const Result r = RunChromium(chromium, page_->html_path, *scratch_,
                               "--screenshot=" + ShellQuote(shot.string()));
  EXPECT_EQ(r.rc, 0) << r.err;
  ASSERT_TRUE(fs::is_regular_file(shot)) << r.err;
  EXPECT_GT(fs::file_size(shot), 20u * 1024u);
  EXPECT_EQ(ReadFile(shot).substr(1, 3), "PNG");
  for (const std::string& line : ScriptProblems(r.err))
    ADD_FAILURE() << "browser console: " << line;
}

TEST_F(LabReport, ItsScriptRunsInChromium) {
  const fs::path chromium = FindOnPath("chromium");
  ASSERT_FALSE(chromium.empty()) << kNoChromium;
  const Result r = RunChromium(chromium, page_->html_path, *scratch_, "--dump-dom");
  ASSERT_EQ(r.rc, 0) << r.err;
  for (const std::string& line : ScriptProblems(r.err))
    ADD_FAILURE() << "browser console: " << line;
  // The selector starts hidden and the script shows it.
  const std::size_t p = r.out.find("id=\"trial-selector\"");
  ASSERT_NE(p, std::string::npos);
  const std::size_t open = r.out.rfind('<', p);
  const std::string tag = r.out.substr(open, r.out.find('>', p) - open);
  EXPECT_EQ(tag.find("hidden"), std::string::npos) << tag;
}

// The console check itself: a page with an uncaught exception and a console.error is caught.
TEST(LabReportBrowserCheck, DetectsScriptErrors) {
  const fs::path chromium = FindOnPath("chromium");
  ASSERT_FALSE(chromium.empty()) << kNoChromium;
  const fs::path work =
      fs::temp_directory_path() / ("echoservo_lab_report_check_" + std::to_string(::getpid()));
  fs::remove_all(work);
  fs::create_directories(work);
  const fs::path html = work / "broken.html";
  std::ofstream(html)
      << "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>x</title></head><body><p>x</p>"
         "<script>console.error('report error');</script><script>noSuchFunction();</script>"
         "</body></html>\n";
  const Result r =
      RunChromium(chromium, html, work, "--screenshot=" + ShellQuote((work / "shot.png").string()));
  const std::vector<std::string> problems = ScriptProblems(r.err);
  fs::remove_all(work);
  bool uncaught = false, console_error = false;
  for (const std::string& line : problems) {
    uncaught = uncaught || line.find("Uncaught") != std::string::npos;
    console_error = console_error || line.find("report error") != std::string::npos;
  }
  EXPECT_TRUE(uncaught) << r.err;
  EXPECT_TRUE(console_error) << r.err;
}

TEST(SvgPlot, DownsamplingKeepsPeaksAndBoundsPoints) {
  std::vector<double> x(100000), y(100000, 0.0);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = 0.001 * static_cast<double>(i);
  y[54321] = 5.0;  // a one-sample spike
  const auto idx = report::svg::DownsampleIndices(x, y);
  EXPECT_LE(idx.size(), report::svg::kMaxPointsPerLine);
  EXPECT_NE(std::find(idx.begin(), idx.end(), 54321u), idx.end());
  EXPECT_TRUE(std::is_sorted(idx.begin(), idx.end()));
  // A loop (x not monotonic): evenly spaced, first and last kept.
  std::vector<double> lx(9000), ly(9000);
  for (std::size_t i = 0; i < lx.size(); ++i)
    lx[i] = std::sin(0.01 * static_cast<double>(i)), ly[i] = lx[i];
  const auto li = report::svg::DownsampleIndices(lx, ly);
  EXPECT_LE(li.size(), report::svg::kMaxPointsPerLine);
  EXPECT_EQ(li.front(), 0u);
  EXPECT_EQ(li.back(), lx.size() - 1);
}

TEST(SvgPlot, TicksAreRoundAndCoverTheRange) {
  const auto t = report::svg::NiceTicks(-0.013, 0.871, 5);
  ASSERT_GE(t.size(), 3u);
  EXPECT_LE(t.front(), -0.013);
  EXPECT_GE(t.back(), 0.871);
  const auto flat = report::svg::NiceTicks(2.0, 2.0, 5);
  EXPECT_LT(flat.front(), flat.back());
  EXPECT_EQ(report::svg::EscapeHtml("a<b>&\"'"), "a&lt;b&gt;&amp;&quot;&#39;");
}

}  // namespace
}  // namespace echoservo
