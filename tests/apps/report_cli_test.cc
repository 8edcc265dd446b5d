// End-to-end test of `echoservo report RUN`: a synthetic RUN directory with the simulated
// EM tracker's log (known constant tip-to-target error), the JSON figures, the HTML page in
// headless Chromium (no script error or console message), and bad input through the CLI:
// the real Aurora export (several sensors; a sensor that does not follow the run), units
// (inches declared or not), a NaN and a time going back in em.csv, a RUN without an EM log.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/test_util/browser.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/synthetic_run.h"
#include "tests/test_util/trial_files.h"

namespace echoservo {
namespace {

namespace fs = std::filesystem;
using testing::ReadFile;
using testing::ReadLines;
using testing::RunCli;
using testing::RunResult;
using testing::ShellQuote;
using testing::SyntheticRun;
using testing::WriteLines;

const fs::path kAurora =
    fs::path(ECHOSERVO_DATA_DIR) / "em_tracker" / "NDIdata_snakeravenTest_2_2_21.csv";

class ReportCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    work_ = new fs::path(fs::temp_directory_path() /
                         ("echoservo_report_cli_" + std::to_string(::getpid())));
    fs::remove_all(*work_);
    run_ = new SyntheticRun;
    run_->em_dropout_every = 17;
    testing::WriteSyntheticRun(*run_, *work_ / "run");
    report_ = new RunResult(RunCli("report " + ShellQuote((*work_ / "run").string()) + " --out " +
                                   ShellQuote(Html().string()) + " --json"));
  }
  static void TearDownTestSuite() {
    fs::remove_all(*work_);
    delete work_;
    delete run_;
    delete report_;
  }
  static fs::path Html() { return *work_ / "report.html"; }
  static fs::path Run() { return *work_ / "run"; }
  // A copy of the run named `name` with em.csv's lines changed by `edit`.
  static fs::path RunWithEm(const std::string& name,
                            const std::function<void(std::vector<std::string>&)>& edit) {
    const fs::path dir = *work_ / name;
    fs::remove_all(dir);
    fs::copy(Run(), dir);
    std::vector<std::string> lines = ReadLines(dir / "em.csv");
    edit(lines);
    WriteLines(dir / "em.csv", lines);
    return dir;
  }
  static RunResult Report(const fs::path& run, const std::string& options = "") {
    return RunCli("report " + ShellQuote(run.string()) + " --out " +
                  ShellQuote((*work_ / "other.html").string()) + " " + options);
  }
  static inline fs::path* work_ = nullptr;
  static inline SyntheticRun* run_ = nullptr;
  static inline RunResult* report_ = nullptr;
};

TEST_F(ReportCli, JsonGivesTheKnownError) {
  ASSERT_EQ(report_->rc, 0) << report_->err;
  const auto j = nlohmann::json::parse(report_->out);
  const SyntheticRun& s = *run_;
  // The tip is the target + d: the RMS is |d| within the interpolation error of the EM
  // track (100 Hz) at the volumes and of the truth (200 Hz) at the EM samples.
  const double a = s.MaxAccelerationMmS2();
  const double tol =
      2 * a * std::pow(1 / s.em_rate_hz, 2) / 8 + a * std::pow(1 / s.truth_rate_hz, 2) / 8;
  EXPECT_NEAR(j["tip_to_target_rms_mm"].get<double>(), s.tip_offset_mm.norm(), tol);
  EXPECT_NEAR(j["em_time_offset_s"].get<double>(), s.em_clock_offset_s, 1e-3);
  EXPECT_LT(j["registration_rms_mm"].get<double>(), tol);
  std::size_t missing = 0;
  for (const auto& e : s.EmSamples()) missing += e.valid ? 0 : 1;
  EXPECT_EQ(j["em_samples"].get<std::size_t>(), s.EmSamples().size());
  EXPECT_EQ(j["em_dropouts"].get<std::size_t>(), missing);
  EXPECT_EQ(j["dropped_frames"].get<std::size_t>(), 0u);
  EXPECT_EQ(j["phase_rms_mm"].size(), 10u);
  EXPECT_FALSE(j["per_beat_rms_mm"].empty());
  EXPECT_NEAR(j["latency_ms"]["p50"].get<double>(), 50.5, 1e-6);
  EXPECT_EQ(j["em_format"], "sim");
}

TEST_F(ReportCli, HtmlRendersInHeadlessChromium) {
  ASSERT_EQ(report_->rc, 0) << report_->err;
  const std::string html = ReadFile(Html());
  testing::browser::ExpectSelfContainedPage(html);
  const fs::path chromium = testing::browser::FindOnPath("chromium");
  ASSERT_FALSE(chromium.empty()) << testing::browser::kNoChromium;
  const fs::path shot = *work_ / "shot.png";
  const RunResult r = testing::browser::RunChromium(chromium, Html(), *work_,
                                                    "--screenshot=" + ShellQuote(shot.string()));
  EXPECT_EQ(r.rc, 0) << r.err;
  ASSERT_TRUE(fs::is_regular_file(shot)) << r.err;
  EXPECT_GT(fs::file_size(shot), 20u * 1024u);
  for (const std::string& line : testing::browser::ScriptProblems(r.err))
    ADD_FAILURE() << "browser console: " << line;
}

TEST_F(ReportCli, TextSummaryWithoutJson) {
  const RunResult r = Report(Run());
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("tip-to-target RMS"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("latency p50/p95/p99/max 50.5/95.0/99.0/100.0 ms"), std::string::npos)
      << r.out;
}

TEST_F(ReportCli, RealAuroraExportIsImportedButRefusedForThisRun) {
  // Four sensors with data: a choice is needed.
  RunResult r = Report(Run(), "--em " + ShellQuote(kAurora.string()));
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("sensors have data; choose one with --sensor"), std::string::npos) << r.err;
  // The bench sensors sat still: they do not follow this run's tip.
  r = Report(Run(), "--em " + ShellQuote(kAurora.string()) + " --sensor d");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("the EM sensor hardly moved"), std::string::npos) << r.err;
}

TEST_F(ReportCli, RealPlusTrackerLogIsImportedButRefusedForThisRun) {
  const fs::path plus = fs::path(ECHOSERVO_DATA_DIR) / "plus" /
                        "WaterTankBottomTranslationTrackerBuffer-trimmed.igs.mha";
  RunResult r = Report(Run(), "--em " + ShellQuote(plus.string()));
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("3 tracked tools; choose one with --sensor"), std::string::npos) << r.err;
  // The stylus lay still in the water tank.
  r = Report(Run(), "--em " + ShellQuote(plus.string()) + " --sensor StylusToTracker");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("the EM sensor hardly moved"), std::string::npos) << r.err;
}

TEST_F(ReportCli, KnownTransformOnTheCommandLine) {
  std::string numbers;
  const Eigen::Matrix4d t = run_->em_to_image.matrix();
  for (int i = 0; i < 16; ++i) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%s%.17g", i ? "," : "", t(i / 4, i % 4));
    numbers += buf;
  }
  RunResult r = Report(Run(), "--json --em-to-image " + numbers);
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["em_to_image_given"].get<bool>());
  EXPECT_NEAR(j["em_time_offset_s"].get<double>(), run_->em_clock_offset_s, 1e-3);
  r = Report(Run(), "--em-to-image 1,0,0,0,1");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("expected 12 or 16 numbers"), std::string::npos) << r.err;
  r = Report(Run(), "--em-to-image 2,0,0,0,0,1,0,0,0,0,1,0");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("not a rigid transform"), std::string::npos) << r.err;
}

TEST_F(ReportCli, UnitsMustBeDeclared) {
  // Inch values under an x_mm header: the scale gives it away.
  auto to_inches = [](std::vector<std::string>& lines) {
    for (std::size_t i = 1; i < lines.size(); ++i) {
      std::vector<std::string> f;
      std::stringstream ss(lines[i]);
      for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
      for (std::size_t k = 1; k <= 3; ++k) f[k] = std::to_string(std::stod(f[k]) / 25.4);
      lines[i] = f[0] + "," + f[1] + "," + f[2] + "," + f[3] + "," + f[4];
    }
  };
  const fs::path undeclared = RunWithEm("inches_as_mm", to_inches);
  RunResult r = Report(undeclared);
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("looks like inches read as mm"), std::string::npos) << r.err;
  // The same values under an x_in header are converted; declaring mm contradicts it.
  const fs::path declared = RunWithEm("inches", [&](std::vector<std::string>& lines) {
    to_inches(lines);
    lines[0] = "t_s,x_in,y_in,z_in,status";
  });
  r = Report(declared, "--json");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NEAR(nlohmann::json::parse(r.out)["tip_to_target_rms_mm"].get<double>(),
              run_->tip_offset_mm.norm(), 0.01);
  r = Report(declared, "--em-units mm");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("positions are in in but mm were declared"), std::string::npos) << r.err;
  r = Report(declared, "--em-units cm");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("\"cm\" is not one of mm, in"), std::string::npos) << r.err;
}

TEST_F(ReportCli, BadEmRowsNameTheLine) {
  const fs::path nan = RunWithEm("nan", [](std::vector<std::string>& lines) {
    lines[41] = "-nan" + lines[41].substr(lines[41].find(','));
  });
  RunResult r = Report(nan);
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("em.csv: line 42: column 't_s': NaN or infinity is not allowed"),
            std::string::npos)
      << r.err;
  const fs::path back =
      RunWithEm("back", [](std::vector<std::string>& lines) { std::swap(lines[30], lines[31]); });
  r = Report(back);
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("em.csv: line 32: column 't_s': times must be strictly increasing"),
            std::string::npos)
      << r.err;
}

TEST_F(ReportCli, RunWithoutEmLogNeedsOne) {
  const fs::path dir = *work_ / "no_em";
  fs::remove_all(dir);
  fs::copy(Run(), dir);
  fs::remove(dir / "em.csv");
  const RunResult r = Report(dir);
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("the run has no em.csv; give the EM log with --em"), std::string::npos)
      << r.err;
  const RunResult missing = Report(*work_ / "nowhere");
  EXPECT_EQ(missing.rc, 1);
  EXPECT_NE(missing.err.find("no such folder"), std::string::npos) << missing.err;
}

}  // namespace
}  // namespace echoservo
