// Trials as a Slurm job array (sbatch) over a STUDY folder every node sees: the tasks are
// listed in STUDY/slurm/<batch>/tasks.txt, a batch script STUDY/slurm/<batch>/job.sh runs
// the task of its SLURM_ARRAY_TASK_ID (tune/executor.h TrialCommand) under `timeout`,
// writing the task's outcome.json itself (exit status, signal, timeout, wall time; beside
// its request.json), and `sbatch --wait --parsable --array=0-(N-1)%max_parallel` submits
// it (several arrays, one after another, where N exceeds the cluster's MaxArraySize). Run
// takes each outcome as its file appears (on_done in completion order) and returns when the
// array has ended (sbatch returns, or squeue lists none of its tasks); a task that never
// wrote an outcome (cancelled, node failure, a folder it cannot write) gets one with the
// state Slurm gives (sacct when available, else `scontrol show job`): "no outcome written
// (Slurm state: …)". SIGINT/SIGTERM while it waits cancels the job (scancel); the
// unfinished tasks' errors then start "interrupted: " (tune/study.cc reruns them).
// docs/tuning_slurm.md; scripts/slurm_local.sh starts a single-node cluster.
// Errors: MakeSlurmExecutor throws std::invalid_argument for bad options; Run reports a
// refused submission (sbatch's exit status and message) in every task's outcome.error.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "tune/executor.h"

namespace echoservo::tune {

struct SlurmExecutorOptions {
  std::string echoservo_exe;
  std::string sbatch = "sbatch";  // the program; a path: scontrol, sacct, squeue, scancel beside it
  std::string partition;          // empty: the cluster's default
  double timeout_s = 600.0;       // per trial (the script's `timeout`, and --time)
  int max_parallel = 0;           // array tasks at once ("%N"); 0: no limit
  std::vector<std::string> extra_args;  // more sbatch arguments (--account=…)
};
std::unique_ptr<TrialExecutor> MakeSlurmExecutor(const SlurmExecutorOptions& o);

}  // namespace echoservo::tune
