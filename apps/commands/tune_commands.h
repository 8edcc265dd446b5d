// `echoservo tune`: offline tuning (docs/tuning.md). `tune SPEC.json --out STUDY [--jobs N |
// --slurm]` runs a study (tune_command.cc, tune/study.h); its subcommands: `tune params`
// (the parameter registry, tune_params_command.cc), `tune trial` (one trial, the process a
// study starts; tune_trial_command.cc) and `tune report STUDY` (tune_report_command.cc).
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddTuneCommand(CLI::App& app);  // `tune` and its subcommands
void AddTuneParamsCommand(CLI::App& tune);
void AddTuneTrialCommand(CLI::App& tune);
void AddTuneReportCommand(CLI::App& tune);

}  // namespace echoservo::apps
