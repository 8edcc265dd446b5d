// `echoservo tune SPEC.json --out STUDY [--jobs N] [--timeout S] [--slurm …] [--json]`:
// runs a tuning study (tune/study.h) on this machine's cores or as a Slurm job array
// (tune/slurm_executor.h); `tune` alone prints its help. The subcommands (params, trial,
// report) are registered here and live in their own files.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/cli.h"
#include "apps/commands/tune_commands.h"
#include "tune/executor.h"
#include "tune/slurm_executor.h"
#include "tune/study.h"
#include "tune/study_files.h"
#include "tune/study_spec.h"

namespace echoservo::apps {
namespace {

struct TuneStudyFlags {
  std::string spec;
  std::string out;
  std::optional<int> jobs;
  std::optional<double> timeout_s;
  bool slurm = false;
  std::string slurm_partition;
  int slurm_max_parallel = 0;
  std::vector<std::string> slurm_args;
  std::string sbatch = "sbatch";
  bool retry_failed = false;
  bool json = false;
};

// The running program, for the trial processes.

void RunTuneStudy(const TuneStudyFlags& f) {
  tune::StudySpec spec = tune::ReadStudySpec(f.spec);
  if (f.jobs) spec.jobs = *f.jobs;
  if (f.timeout_s) spec.timeout_s = *f.timeout_s;
  std::unique_ptr<tune::TrialExecutor> executor;
  if (f.slurm) {
    tune::SlurmExecutorOptions o;
    o.echoservo_exe = ProgramPath();
    o.sbatch = f.sbatch;
    o.partition = f.slurm_partition;
    o.timeout_s = spec.timeout_s;
    o.max_parallel = f.slurm_max_parallel;
    o.extra_args = f.slurm_args;
    executor = tune::MakeSlurmExecutor(o);
  } else {
    tune::LocalExecutorOptions o;
    o.echoservo_exe = ProgramPath();
    o.jobs = spec.jobs;
    o.timeout_s = spec.timeout_s;
    executor = tune::MakeLocalExecutor(o);
  }
  std::ostream& progress = f.json ? std::cerr : std::cout;
  if (f.retry_failed && std::filesystem::exists(std::filesystem::path(f.out) / "study.json") &&
      tune::ReadStudyHeader(f.out).spec_json == spec.normalised_json) {
    // Every failed trial runs again: its result goes (a crash or a timeout runs again anyway).
    std::size_t n = 0;
    for (const tune::StudyTrial& t : tune::ReadTrials(f.out)) {
      if (!t.result || t.result->status == "ok") continue;
      std::error_code ec;
      std::filesystem::remove(tune::TrialDir(f.out, t.id) / "result.json", ec);
      if (!ec) ++n;
    }
    progress << "--retry-failed: " << n << " failed trial(s) will run again" << std::endl;
  }
  const tune::StudySummary s = tune::RunStudy(
      spec, f.out, *executor, [&](const std::string& line) { progress << line << std::endl; });
  const std::string report = "echoservo tune report " + f.out + " --out study.html";
  if (f.json) {
    const nlohmann::json j = {{"study", std::filesystem::absolute(f.out).string()},
                              {"executor", executor->name()},
                              {"objective", spec.metric},
                              {"minimize", spec.minimize},
                              {"search", spec.method},
                              {"recordings", spec.recordings.size()},
                              {"sets", s.sets},
                              {"trials", s.trials},
                              {"skipped", s.skipped},
                              {"ran", s.ran},
                              {"failed", s.failed},
                              {"wall_s", s.wall_s},
                              {"report", report}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << "study " << f.out << ": " << s.sets << " set(s) × " << spec.recordings.size()
              << " recording(s) = " << s.trials << " trial(s): " << s.skipped
              << " finished before (skipped), " << s.ran << " ran now, " << s.failed << " failed, "
              << s.wall_s << " s\n"
              << "report: " << report << "\n";
  }
  if (s.trials > 0 && s.failed == s.trials) {
    std::string first;
    for (const tune::StudyTrial& t : tune::ReadTrials(f.out)) {
      if (t.result && t.result->status != "ok") {
        first = t.id + ": " + t.result->reason;
        break;
      }
    }
    throw std::runtime_error("tune: every trial failed (" + first + ")");
  }
}

}  // namespace

void AddTuneCommand(CLI::App& app) {
  CLI::App* tune = app.add_subcommand(
      "tune",
      "Offline tuning: sweep the tracker path's parameters over recordings and score them "
      "(`tune SPEC.json --out STUDY`; docs/tuning.md)");
  auto f = std::make_shared<TuneStudyFlags>();
  tune->add_option("SPEC", f->spec, "the study's SPEC (JSON; docs/tuning.md)");
  tune->add_option("--out", f->out,
                   "STUDY folder: every trial's request, result and log (created; a rerun "
                   "skips finished trials)");
  tune->add_option("--jobs", f->jobs,
                   "trial processes at once (default: the SPEC's, else 0: "
                   "the cores available)")
      ->check(CLI::Range(0, 4096));
  tune->add_option("--timeout", f->timeout_s,
                   "per trial, s: killed after it and recorded as failed (default: the SPEC's "
                   "timeout_s, else 600)")
      ->check(CLI::Range(1e-3, 86400.0));
  tune->add_flag("--slurm", f->slurm,
                 "submit the trials as a Slurm job array (sbatch) over the STUDY folder, which "
                 "every node must see");
  tune->add_option("--slurm-partition", f->slurm_partition, "--slurm: the partition");
  tune->add_option("--slurm-max-parallel", f->slurm_max_parallel,
                   "--slurm: array tasks at once (0: no limit)")
      ->check(CLI::Range(0, 1000000));
  tune->add_option("--slurm-arg", f->slurm_args,
                   "--slurm: one more sbatch argument, repeatable (--slurm-arg=--account=lab)")
      ->allow_extra_args(false);  // one value per flag: the SPEC after it stays the SPEC
  tune->add_option("--sbatch", f->sbatch, "--slurm: the sbatch program (default: sbatch)");
  tune->add_flag("--retry-failed", f->retry_failed,
                 "run every failed trial again, also those that failed on their input (a rerun "
                 "always retries crashes and timeouts)");
  tune->add_flag("--json", f->json, "print the study's summary as JSON (progress on stderr)");
  AddTuneParamsCommand(*tune);
  AddTuneTrialCommand(*tune);
  AddTuneReportCommand(*tune);
  tune->callback([tune, f] {
    if (!tune->get_subcommands().empty()) return;  // `tune params|trial|report` ran
    if (f->spec.empty()) {
      std::cout << tune->help();
      return;
    }
    if (f->out.empty())
      throw std::invalid_argument("tune " + f->spec + ": --out STUDY is required");
    const bool slurm_only = !f->slurm_partition.empty() || f->slurm_max_parallel != 0 ||
                            !f->slurm_args.empty() || f->sbatch != "sbatch";
    if (slurm_only && !f->slurm) {
      throw std::invalid_argument(
          "tune: --slurm-partition, --slurm-max-parallel, --slurm-arg and --sbatch need --slurm");
    }
    if (f->slurm && f->jobs)
      throw std::invalid_argument(
          "tune: --jobs is for local runs, not --slurm (use --slurm-max-parallel)");
    RunTuneStudy(*f);
  });
}

}  // namespace echoservo::apps
