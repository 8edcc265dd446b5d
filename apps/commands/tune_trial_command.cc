// `echoservo tune trial`: one tuning trial (tune/trial.h). The study's process:
//   tune trial --request REQ.json --out RESULT.json
// always writes RESULT.json (crash-safe), status "ok" or "failed" with the reason; exit 0
// when ok, 2 when failed. For people:
//   tune trial --recording R [--em EM.csv] [--set a=b]... [--latency S] [--delay S]
//              [--from S] [--seed N] [--no-loop] [--json] [--keep DIR]
// prints the metrics; --keep DIR writes the per-volume and loop CSVs (docs/tuning.md).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include "apps/commands/set_flags.h"
#include "apps/commands/tune_commands.h"
#include "formats/durable_file.h"
#include "tune/trial.h"

namespace echoservo::apps {
namespace {

struct TuneTrialArgs {
  std::string request, out, recording, em, keep;
  SetFlags set;
  double latency_s = 0.1, delay_s = -1.0, from_s = 3.0;
  std::uint64_t seed = 1;
  bool no_loop = false, json = false;
};

std::string TuneTrialReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument("--request " + path + ": cannot be read");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void TuneTrialPrint(const tune::TrialResult& r, const std::string& recording) {
  std::cout << "trial on " << recording << ": " << r.volumes << " volumes, " << r.measured
            << " measured, " << r.errors << " errors";
  if (r.skipped > 0) std::cout << ", " << r.skipped << " skipped";
  std::cout << "\n";
  for (const tune::MetricInfo& m : tune::Metrics()) {
    const auto it = r.metrics.find(m.name);
    char line[160];
    if (it == r.metrics.end()) {
      std::snprintf(line, sizeof line, "  %-30s %12s\n", m.name.c_str(), "-");
    } else {
      std::snprintf(line, sizeof line, "  %-30s %12.4f %s\n", m.name.c_str(), it->second,
                    m.unit.c_str());
    }
    std::cout << line;
  }
  for (const std::string& n : r.notes) std::cout << "note: " << n << "\n";
  char times[160];
  std::snprintf(times, sizeof times, "times: load %.3f s, replay %.3f s, score %.3f s\n", r.load_s,
                r.replay_s, r.score_s);
  std::cout << times;
}

void TuneTrialRun(const TuneTrialArgs& a) {
  if (!a.request.empty()) {
    if (a.out.empty()) throw std::invalid_argument("tune trial --request: needs --out RESULT.json");
    if (!a.recording.empty() || !a.set.assignments.empty())
      throw std::invalid_argument(
          "tune trial: --request carries the recording and settings; drop --recording/--set");
    tune::TrialResult r;
    std::optional<tune::TrialTrace> trace;
    if (!a.keep.empty()) trace.emplace();
    try {
      const tune::TrialRequest req = tune::RequestFromJson(TuneTrialReadFile(a.request), a.request);
      r = tune::RunTrial(req, trace ? &*trace : nullptr);
      if (trace) tune::WriteTrialTrace(*trace, a.keep);
    } catch (const std::exception& e) {
      r = tune::TrialResult{};
      r.status = "failed";
      r.reason = e.what();
    }
    formats::ReplaceFileContents(a.out, tune::ResultToJson(r));
    if (a.json) std::cout << tune::ResultToJson(r) << "\n";
    if (r.status != "ok") {
      std::cerr << "tune trial: failed: " << r.reason << "\n";
      throw CLI::RuntimeError(2);
    }
    return;
  }
  if (a.recording.empty())
    throw std::invalid_argument("tune trial: give --recording R (or --request REQ.json --out R)");
  tune::TrialRequest req;
  req.recording = a.recording;
  req.em_log = a.em;
  req.settings = a.set.Parsed();
  req.latency_s = a.latency_s;
  req.delay_s = a.delay_s;
  req.from_s = a.from_s;
  req.seed = a.seed;
  req.loop = !a.no_loop;
  std::optional<tune::TrialTrace> trace;
  if (!a.keep.empty()) trace.emplace();
  const tune::TrialResult r = tune::RunTrial(req, trace ? &*trace : nullptr);
  if (trace) tune::WriteTrialTrace(*trace, a.keep);
  if (!a.out.empty()) formats::ReplaceFileContents(a.out, tune::ResultToJson(r));
  if (a.json) {
    std::cout << tune::ResultToJson(r) << "\n";
  } else {
    TuneTrialPrint(r, a.recording);
  }
}

}  // namespace

void AddTuneTrialCommand(CLI::App& tune) {
  auto* cmd = tune.add_subcommand(
      "trial", "one trial: replay a recording with one parameter set and score it (tune/trial.h)");
  auto a = std::make_shared<TuneTrialArgs>();
  cmd->add_option("--request", a->request,
                  "a trial request (JSON, tune/trial.h RequestToJson): the study's process");
  cmd->add_option("--out", a->out,
                  "write the result JSON here (crash-safe); with --request always written");
  cmd->add_option("--recording", a->recording,
                  "a PLUS sequence (.igs.mha/.igs.mhd/.igs.nrrd) or a RUN directory");
  cmd->add_option("--em", a->em, "the recording's EM log (default: RUN/em.csv when present)");
  AddSetFlags(*cmd, a->set);
  cmd->add_option("--latency", a->latency_s, "working latency predictions are scored at, s")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--delay", a->delay_s,
                  "re-simulated loop: estimates delivered this long after acquisition, s "
                  "(negative: --latency)")
      ->check(CLI::Range(-1.0, 1.0));
  cmd->add_option("--from", a->from_s, "scores start this long after the first volume, s")
      ->check(CLI::Range(0.0, 60.0));
  cmd->add_option("--seed", a->seed, "the simulated plant's noise seed");
  cmd->add_flag("--no-loop", a->no_loop, "do not re-simulate the closed loop (faster)");
  cmd->add_option("--keep", a->keep,
                  "write volumes.csv (per volume) and loop.csv (every 10 servo cycles) here");
  cmd->add_flag("--json", a->json, "print the result as JSON");
  cmd->callback([a] { TuneTrialRun(*a); });
}

}  // namespace echoservo::apps
