// The STUDY folder of `echoservo tune`: every trial's request and result on disk, written
// crash-safe (formats/durable_file.h: write to a temporary, fsync, rename), so a study that is
// killed keeps every finished trial and a rerun skips them.
//
//   STUDY/study.json                 StudyHeader (the normalised SPEC and what it expands to)
//   STUDY/trials/<id>/request.json   the trial's TrialRequest + its set and recording
//   STUDY/trials/<id>/result.json    the trial's TrialResult (written by the trial process,
//                                    or by the study for a trial that crashed or timed out)
//   STUDY/trials/<id>/outcome.json   how the process ended (the executor's TaskOutcome)
//   STUDY/trials/<id>/log.txt        the trial process's stdout and stderr
// Trial ids: "s<set>-r<recording>", zero-padded ("s0003-r01"); set 0 is always the default
// settings (live::DefaultSettings(): the baseline every other set is compared with).
// The files (JSON objects; other keys are ignored when read):
//   study.json    {"format": "echoservo-study", "version": 1, "spec_json": "<the SPEC as a
//                  string, byte for byte>", "spec_path", "objective", "minimize", "search",
//                  "parameters": [..], "recordings": [..], "recording_names": [..],
//                  "em_logs": [..], "created_utc"}
//   request.json  RequestToJson (tune/trial.h), exactly: the file `tune trial --request`
//                 reads (RequestFromJson refuses unknown fields); the set and recording
//                 are the folder's id. ReadTrials also accepts (and drops) "id",
//                 "set_index" and "recording_index" keys, which must then agree.
//   result.json   ResultToJson (tune/trial.h)
//   outcome.json  {"id": "s0003-r01", "exit_code": 0, "signal": 0, "timed_out": false,
//                  "wall_s": 12.5, "error": ""}: exit_code -1 when the process did not exit
//                  (signal or timeout), wall_s null when unknown; the Slurm job script
//                  (tune/slurm_executor.h) writes this file itself with the same fields.
// Errors: std::invalid_argument naming the file and why for a malformed file;
// std::runtime_error when a file cannot be written.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tune/trial.h"

namespace echoservo::tune {

struct StudyHeader {
  std::string spec_json;  // the SPEC as read (normalised JSON)
  std::string spec_path;  // where it was read from
  std::string objective;  // a metric name (tune/trial.h)
  bool minimize = true;
  std::string search;                        // "grid", "random", "adaptive"
  std::vector<std::string> parameters;       // the tuned names
  std::vector<std::string> recordings;       // absolute paths, index = r
  std::vector<std::string> recording_names;  // short unique names for reports
  std::vector<std::string> em_logs;          // per recording, "" when none
  std::string created_utc;
};

struct TaskOutcome {
  std::string id;
  int exit_code = -1;  // the process's exit status; -1 when it did not exit
  int signal = 0;      // the signal that ended it, 0 when none
  bool timed_out = false;
  double wall_s = 0.0;  // process start to end, as the executor measured it
  std::string error;    // could not start / submit, with why
};

struct StudyTrial {
  std::string id;
  int set_index = 0;
  int recording_index = 0;
  TrialRequest request;
  std::optional<TrialResult> result;   // nullopt: not finished
  std::optional<TaskOutcome> outcome;  // nullopt: not recorded
};

std::string TrialId(int set_index, int recording_index);
std::filesystem::path TrialDir(const std::filesystem::path& study, const std::string& id);

void WriteStudyHeader(const std::filesystem::path& study, const StudyHeader& h);
StudyHeader ReadStudyHeader(const std::filesystem::path& study);

void WriteTrialRequest(const std::filesystem::path& study, const StudyTrial& t);
void WriteTrialResult(const std::filesystem::path& study, const std::string& id,
                      const TrialResult& r);
void WriteTaskOutcome(const std::filesystem::path& study, const TaskOutcome& o);

// outcome.json's text, and back (throws std::invalid_argument naming `where` and the
// field; "id" and "exit_code" are required, the other fields default as in TaskOutcome).
std::string TaskOutcomeToJson(const TaskOutcome& o);
TaskOutcome TaskOutcomeFromJson(std::string_view json, std::string_view where);

// Every trial with a request.json, sorted by id; result/outcome filled where present. A
// result.json that does not parse (a crash mid-write cannot make one, a hand edit can) is
// reported in `problems` and the trial counts as unfinished. Likewise a malformed
// outcome.json (outcome nullopt; a valid result.json still counts) and a malformed
// request.json (the trial is left out). Leftover "*.tmp" files of a killed write are ignored.
std::vector<StudyTrial> ReadTrials(const std::filesystem::path& study,
                                   std::vector<std::string>* problems = nullptr);

}  // namespace echoservo::tune
