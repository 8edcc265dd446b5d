// Where a study's trials run: each trial is one process,
//   <echoservo> tune trial --request STUDY/trials/<id>/request.json
//                          --out STUDY/trials/<id>/result.json
// with its stdout and stderr in STUDY/trials/<id>/log.txt. Locally (MakeLocalExecutor) up to
// `jobs` processes at once on this machine, each killed after timeout_s; on a Slurm cluster
// (tune/slurm_executor.h) as one job array over the shared STUDY folder. An executor records
// how each process ended (TaskOutcome, STUDY/trials/<id>/outcome.json); it never writes
// result.json (the study does that for a trial that ended without one).
// Errors: the constructors throw std::invalid_argument for bad options; Run never throws for
// one task's failure (it is in that task's outcome).
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "tune/study_files.h"

namespace echoservo::tune {

struct TrialTask {
  std::string id;
  std::filesystem::path request, result, log;
};

// The argv of one trial process.
std::vector<std::string> TrialCommand(const std::string& echoservo_exe, const TrialTask& t);

class TrialExecutor {
 public:
  virtual ~TrialExecutor() = default;
  // Runs every task; `on_done` (may be null) is called once per task as it ends, on the
  // calling thread, in completion order. Returns the outcomes in task order.
  virtual std::vector<TaskOutcome> Run(const std::vector<TrialTask>& tasks,
                                       const std::function<void(const TaskOutcome&)>& on_done) = 0;
  virtual std::string name() const = 0;  // "local (2 jobs)", "slurm (job 42)"
};

struct LocalExecutorOptions {
  std::string echoservo_exe;  // the program to start (the running one: /proc/self/exe)
  int jobs = 0;               // processes at once; 0: the cores available
  double timeout_s = 600.0;   // per trial, (0, 86400]
};
std::unique_ptr<TrialExecutor> MakeLocalExecutor(const LocalExecutorOptions& o);

}  // namespace echoservo::tune
