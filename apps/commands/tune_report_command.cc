// `echoservo tune report STUDY [--out study.html] [--json] [--bootstrap N] [--confidence C]
// [--seed S]`: what a tuning study found (tune/study_report.h): the HTML page (--out; by
// default STUDY/report.html unless --json is given alone) and, with --json, the same content
// as JSON on stdout. Without --json it prints the best set and the verdict against the
// default settings.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "apps/commands/tune_commands.h"
#include "apps/output.h"
#include "tune/study_report.h"

namespace echoservo::apps {
namespace {

struct TuneReportArgs {
  std::string study;
  std::string out;
  bool json = false;
  tune::StudyReportOptions options;
};

void TuneReportWritePage(const std::string& out, const std::string& page) {
  std::error_code ec;
  if (std::filesystem::is_directory(out, ec)) {
    throw std::invalid_argument("tune report --out " + out +
                                ": is a folder; give the HTML file to write (e.g. " +
                                (std::filesystem::path(out) / "study.html").string() + ")");
  }
  try {
    WriteFileAtomically(out, page);
  } catch (const std::exception& e) {
    std::filesystem::remove(out + ".tmp", ec);
    throw std::invalid_argument("tune report --out " + out + ": cannot write the report (" +
                                e.what() + ")");
  }
}

void TuneReportRun(const TuneReportArgs& a) {
  std::error_code ec;
  if (!std::filesystem::is_directory(a.study, ec)) {
    throw std::invalid_argument("tune report " + a.study +
                                ": no such STUDY folder (the --out of `echoservo tune "
                                "SPEC.json --out STUDY`)");
  }
  std::string out = a.out;
  if (out.empty() && !a.json) out = (std::filesystem::path(a.study) / "report.html").string();
  const std::string json_text = tune::StudyReportJson(a.study, a.options);
  if (!out.empty()) TuneReportWritePage(out, tune::StudyReportHtml(a.study, a.options));
  if (a.json) {
    std::cout << json_text << "\n";
    return;
  }
  const nlohmann::json j = nlohmann::json::parse(json_text);
  const auto& t = j["trials"];
  std::cout << "wrote " << out << "\n"
            << "trials: " << t["finished"].get<std::size_t>() << " finished, "
            << t["failed"].get<std::size_t>() << " failed, " << t["pending"].get<std::size_t>()
            << " not run, of " << t["total"].get<std::size_t>() << "\n";
  const std::string unit = j["unit"].get<std::string>();
  if (!j["best"].is_null()) {
    const auto& b = j["best"];
    std::cout << "best set " << b["set"].get<int>() << ": "
              << (b["assignments"].get<std::string>().empty() ? std::string("(default settings)")
                                                              : b["assignments"].get<std::string>())
              << "\n  mean " << j["objective"].get<std::string>() << " "
              << (b["mean"].is_number() ? Fixed(b["mean"].get<double>(), 4) : std::string("-"))
              << " " << unit << "; default "
              << (b["default_mean"].is_number() ? Fixed(b["default_mean"].get<double>(), 4)
                                                : std::string("-"))
              << " " << unit << "\n";
  }
  std::cout << j["verdict"].get<std::string>() << "\n";
  if (!j["failures"].empty())
    std::cout << j["failures"].size() << " failed trials (listed in the report)\n";
  for (const auto& p : j["problems"]) std::cout << "problem: " << p.get<std::string>() << "\n";
}

}  // namespace

void AddTuneReportCommand(CLI::App& tune) {
  auto* cmd = tune.add_subcommand(
      "report", "what a tuning study found: best settings with confidence intervals (HTML/JSON)");
  auto a = std::make_shared<TuneReportArgs>();
  cmd->add_option("STUDY", a->study, "the STUDY folder of `echoservo tune SPEC.json --out STUDY`")
      ->required();
  cmd->add_option("--out", a->out,
                  "write the HTML report here (default: STUDY/report.html unless --json)");
  cmd->add_flag("--json", a->json, "print the report as JSON on stdout");
  cmd->add_option("--bootstrap", a->options.bootstrap_samples,
                  "bootstrap resamples for the confidence intervals")
      ->check(CLI::Range(100, 1000000));
  cmd->add_option("--confidence", a->options.confidence,
                  "confidence level of the intervals, in (0, 1)")
      ->check(CLI::Range(0.5, 0.999));
  cmd->add_option("--seed", a->options.seed, "the bootstrap's and Monte Carlo test's seed");
  cmd->callback([a] { TuneReportRun(*a); });
}

}  // namespace echoservo::apps
