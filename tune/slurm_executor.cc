#include "tune/slurm_executor.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include "formats/durable_file.h"
#include "tune/interrupt.h"

extern char** environ;

namespace echoservo::tune {
namespace {

namespace fs = std::filesystem;

// Slurm's default MaxArraySize (array indices 0 .. MaxArraySize-1).
constexpr int kSlurmDefaultMaxArraySize = 1001;
// job.sh's `timeout --kill-after`: SIGKILL this long after the SIGTERM.
constexpr int kSlurmKillAfterS = 5;

// One word for bash: single-quoted, with control characters as $'\xHH' pieces, so a task
// stays on one line of tasks.txt whatever its paths contain.
std::string SlurmShellQuote(std::string_view s) {
  std::string q = "'";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '\'') {
      q += "'\\''";
    } else if (u < 0x20 || u == 0x7f) {
      char hex[16];
      std::snprintf(hex, sizeof hex, "'$'\\x%02x''", u);
      q += hex;
    } else {
      q += c;
    }
  }
  q += "'";
  return q;
}

std::string SlurmJsonString(std::string_view s) {
  std::string j = "\"";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      j += '\\';
      j += c;
    } else if (u < 0x20) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\u%04x", u);
      j += hex;
    } else {
      j += c;
    }
  }
  j += "\"";
  return j;
}

std::string SlurmTrim(std::string s) {
  const auto not_space = [](unsigned char c) { return !std::isspace(c); };
  s.erase(s.begin(), std::find_if(s.begin(), s.end(), not_space));
  s.erase(std::find_if(s.rbegin(), s.rend(), not_space).base(), s.end());
  return s;
}

std::string SlurmReadFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A command's end: `spawn_error` when it could not start, else its exit status (or the
// signal that ended it) and what it printed.
struct SlurmCommandResult {
  std::string spawn_error;
  int status = -1;  // exit status; -1 when it did not exit
  int signal = 0;
  std::string out, err;
};

// Starts argv[0] (searched in PATH) with this process's environment (SLURM_CONF included),
// stdout and stderr to files under `scratch`, stdin from /dev/null; in a process group of
// its own when `own_group` (so that Ctrl-C in a terminal reaches only the study, which
// cancels the job). -1 and `error` when it could not start.
pid_t SlurmSpawn(const std::vector<std::string>& argv, const fs::path& scratch,
                 const std::string& stem, bool own_group, std::string& error) {
  const fs::path out_path = scratch / (stem + ".out");
  const fs::path err_path = scratch / (stem + ".err");
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                   0644);
  posix_spawn_file_actions_addopen(&actions, 2, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                   0644);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  if (own_group) {
    posix_spawnattr_setpgroup(&attr, 0);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
  }
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, args[0], &actions, &attr, args.data(), environ);
  posix_spawnattr_destroy(&attr);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    error = "cannot run '" + argv[0] + "': " + std::strerror(rc);
    return -1;
  }
  return pid;
}

// The end of a process SlurmSpawn started (`wstatus` from waitpid).
SlurmCommandResult SlurmCollect(const std::string& program, int wstatus, const fs::path& scratch,
                                const std::string& stem) {
  SlurmCommandResult r;
  if (WIFEXITED(wstatus)) r.status = WEXITSTATUS(wstatus);
  if (WIFSIGNALED(wstatus)) r.signal = WTERMSIG(wstatus);
  r.out = SlurmReadFile(scratch / (stem + ".out"));
  r.err = SlurmReadFile(scratch / (stem + ".err"));
  // A program that is missing or not executable: the child's exec fails with 127.
  if (r.status == 127 && r.out.empty() && r.err.empty())
    r.spawn_error = "cannot run '" + program + "': not found or not executable";
  return r;
}

// Waits for `pid`; with `nohang`, returns false at once while it runs. True when it has
// ended (`wstatus` set; 0 when it is somehow no longer our child).
bool SlurmWait(pid_t pid, bool nohang, int& wstatus) {
  for (;;) {
    const pid_t w = ::waitpid(pid, &wstatus, nohang ? WNOHANG : 0);
    if (w == pid) return true;
    if (w == 0) return false;
    if (errno == EINTR) {
      if (nohang) return false;
      continue;
    }
    wstatus = 0;
    return true;
  }
}

// Runs a short query command to its end.
SlurmCommandResult SlurmRunCommand(const std::vector<std::string>& argv, const fs::path& scratch,
                                   const std::string& stem) {
  SlurmCommandResult r;
  const pid_t pid = SlurmSpawn(argv, scratch, stem, false, r.spawn_error);
  if (pid < 0) return r;
  int wstatus = 0;
  SlurmWait(pid, false, wstatus);
  return SlurmCollect(argv[0], wstatus, scratch, stem);
}

// The program `name` beside `sbatch` when that is a path (a test's cluster), else `name`.
std::string SlurmSibling(const std::string& sbatch, const std::string& name) {
  if (sbatch.find('/') == std::string::npos) return name;
  const fs::path p = fs::path(sbatch).parent_path() / name;
  std::error_code ec;
  return fs::exists(p, ec) ? p.string() : name;
}

// The batch script: runs task OFFSET + SLURM_ARRAY_TASK_ID of tasks.txt (one line of bash
// words: id, id as JSON, request, result, log, outcome, then the trial's argv) under
// `timeout`, its output to the log, and writes outcome.json (tune/study_files.h
// TaskOutcomeToJson's fields) through a temporary, fsync and rename.
std::string SlurmJobScript(const fs::path& batch, double timeout_s) {
  char timeout_text[64];
  std::snprintf(timeout_text, sizeof timeout_text, "%.3f", timeout_s);
  std::ostringstream s;
  s << "#!/bin/bash\n"
       "# Written by echoservo (tune/slurm_executor.cc): one array task of a tuning study.\n"
       "# Usage (sbatch --array=0-N): job.sh OFFSET; runs line OFFSET+SLURM_ARRAY_TASK_ID of\n"
       "# tasks.txt and writes that trial's outcome.json.\n"
       "set -u\n"
       "export LC_ALL=C\n"
       "ulimit -c 0\n"
       "batch="
    << SlurmShellQuote(batch.string())
    << "\n"
       "timeout_s="
    << timeout_text
    << "\n"
       "offset=${1:-0}\n"
       "index=$((offset + ${SLURM_ARRAY_TASK_ID:-0}))\n"
       "mapfile -t -s \"$index\" -n 1 lines <\"$batch/tasks.txt\"\n"
       "line=${lines[0]:-}\n"
       "if [[ -z \"$line\" ]]; then\n"
       "  echo \"job.sh: no task $index in $batch/tasks.txt\" >&2\n"
       "  exit 3\n"
       "fi\n"
       "eval \"task=($line)\"\n"
       "id_json=${task[1]}\n"
       "log=${task[4]}\n"
       "outcome=${task[5]}\n"
       "exit_code=-1\n"
       "signal=0\n"
       "timed_out=false\n"
       "error=\"\"\n"
       "start=$EPOCHREALTIME\n"
       "if ! { printf '$'; printf ' %s' \"${task[@]:6}\"; printf '\\n'; } >\"$log\"; then\n"
       "  error=\"cannot write the trial's log on $(hostname -s)\"\n"
       "  status=-1\n"
       "else\n"
       "  timeout --signal=TERM --kill-after="
    << kSlurmKillAfterS
    << " \"$timeout_s\" \"${task[@]:6}\" >>\"$log\" 2>&1 </dev/null\n"
       "  status=$?\n"
       "fi\n"
       "end=$EPOCHREALTIME\n"
       "us=$((10#${end/./} - 10#${start/./}))\n"
       "printf -v wall '%d.%06d' $((us / 1000000)) $((us % 1000000))\n"
       "if ((status == 124)); then\n"
       "  timed_out=true\n"
       "  signal=15\n"
       "elif ((status == 137)) && ((us >= 10#${timeout_s/./} * 1000)); then\n"
       "  timed_out=true\n"
       "  signal=9\n"
       "elif ((status == 125 || status == 126 || status == 127)); then\n"
       "  error=\"could not start the trial process on $(hostname -s) (timeout's status "
       "$status; see the log)\"\n"
       "elif ((status > 128)); then\n"
       "  signal=$((status - 128))\n"
       "elif ((status >= 0)); then\n"
       "  exit_code=$status\n"
       "fi\n"
       "tmp=\"$outcome.tmp.$$\"\n"
       "printf '{\\n  \"id\": %s,\\n  \"exit_code\": %d,\\n  \"signal\": %d,\\n  "
       "\"timed_out\": %s,\\n  \"wall_s\": %s,\\n  \"error\": \"%s\"\\n}\\n' \\\n"
       "  \"$id_json\" \"$exit_code\" \"$signal\" \"$timed_out\" \"$wall\" \"$error\" "
       ">\"$tmp\" &&\n"
       "  { sync \"$tmp\" 2>/dev/null || true; } &&\n"
       "  mv -f \"$tmp\" \"$outcome\" || exit 4\n"
       "exit 0\n";
  return s.str();
}

// The Slurm state of each array index of `job_id` ("" where unknown): sacct where
// accounting works, else `scontrol show job` (while the controller still holds the job).
std::map<int, std::string> SlurmTaskStates(const SlurmExecutorOptions& o, const std::string& job_id,
                                           const fs::path& scratch) {
  std::map<int, std::string> states;
  const SlurmCommandResult sacct = SlurmRunCommand(
      {SlurmSibling(o.sbatch, "sacct"), "-n", "-P", "-X", "-j", job_id, "-o", "JobID,State"},
      scratch, "sacct");
  if (sacct.spawn_error.empty() && sacct.status == 0) {
    std::istringstream lines(sacct.out);
    std::string line;
    while (std::getline(lines, line)) {
      const auto bar = line.find('|');
      const auto under = line.find('_');
      if (bar == std::string::npos || under == std::string::npos || under > bar) continue;
      const std::string index = line.substr(under + 1, bar - under - 1);
      if (index.empty() || !std::all_of(index.begin(), index.end(), ::isdigit)) continue;
      states[std::stoi(index)] = SlurmTrim(line.substr(bar + 1));
    }
    if (!states.empty()) return states;
  }
  const SlurmCommandResult show = SlurmRunCommand(
      {SlurmSibling(o.sbatch, "scontrol"), "-o", "show", "job", job_id}, scratch, "scontrol");
  if (!show.spawn_error.empty() || show.status != 0) return states;
  std::istringstream lines(show.out);
  std::string line;
  while (std::getline(lines, line)) {
    std::map<std::string, std::string> fields;
    std::istringstream words(line);
    std::string word;
    while (words >> word) {
      const auto eq = word.find('=');
      if (eq != std::string::npos) fields[word.substr(0, eq)] = word.substr(eq + 1);
    }
    std::string state = fields["JobState"];
    if (state.empty()) continue;
    if (!fields["Reason"].empty() && fields["Reason"] != "None")
      state += ", reason " + fields["Reason"];
    // ArrayTaskId: "3", or pending ones as "4-9", "4,6-9%2".
    std::string ids = fields["ArrayTaskId"];
    ids = ids.substr(0, ids.find('%'));
    std::istringstream parts(ids);
    std::string part;
    while (std::getline(parts, part, ',')) {
      try {
        const auto dash = part.find('-');
        const int a = std::stoi(part.substr(0, dash));
        const int b = dash == std::string::npos ? a : std::stoi(part.substr(dash + 1));
        for (int i = a; i <= b && i - a < 1000000; ++i) states[i] = state;
      } catch (const std::exception&) {
      }
    }
  }
  return states;
}

// Whether job `job_id` has no task left in the queue (pending, running, completing):
// squeue answers and lists none. Any doubt (squeue failing, a job id it does not know any
// more) is false: sbatch --wait decides then.
bool SlurmLeftQueue(const SlurmExecutorOptions& o, const std::string& job_id,
                    const fs::path& scratch) {
  const SlurmCommandResult r = SlurmRunCommand({SlurmSibling(o.sbatch, "squeue"), "--noheader",
                                                "--array", "--jobs=" + job_id, "--format=%i"},
                                               scratch, "squeue");
  return r.spawn_error.empty() && r.status == 0 && SlurmTrim(r.out).empty();
}

int SlurmMaxArraySize(const SlurmExecutorOptions& o, const fs::path& scratch) {
  const SlurmCommandResult r =
      SlurmRunCommand({SlurmSibling(o.sbatch, "scontrol"), "show", "config"}, scratch, "config");
  if (!r.spawn_error.empty() || r.status != 0) return kSlurmDefaultMaxArraySize;
  std::istringstream lines(r.out);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind("MaxArraySize", 0) != 0) continue;
    const auto eq = line.find('=');
    if (eq == std::string::npos) break;
    try {
      const int n = std::stoi(line.substr(eq + 1));
      if (n >= 1) return n;
    } catch (const std::exception&) {
    }
    break;
  }
  return kSlurmDefaultMaxArraySize;
}

// The STUDY folder of a task (STUDY/trials/<id>/request.json), else the request's folder.
fs::path SlurmStudyOf(const TrialTask& t) {
  const fs::path trial_dir = t.request.parent_path();
  if (trial_dir.parent_path().filename() == "trials") return trial_dir.parent_path().parent_path();
  return trial_dir;
}

fs::path SlurmOutcomePath(const TrialTask& t) { return t.request.parent_path() / "outcome.json"; }

// The job id sbatch --parsable printed ("<id>[;<cluster>]"), "" when none.
std::string SlurmJobId(const std::string& out) {
  std::string id = SlurmTrim(out.substr(0, out.find('\n')));
  id = id.substr(0, id.find(';'));
  if (id.empty() || !std::all_of(id.begin(), id.end(), ::isdigit)) return "";
  return id;
}

class SlurmExecutor final : public TrialExecutor {
 public:
  explicit SlurmExecutor(SlurmExecutorOptions o) : o_(std::move(o)) {}

  std::vector<TaskOutcome> Run(const std::vector<TrialTask>& tasks,
                               const std::function<void(const TaskOutcome&)>& on_done) override {
    std::vector<TaskOutcome> outcomes(tasks.size());
    std::vector<bool> done(tasks.size(), false);
    for (std::size_t i = 0; i < tasks.size(); ++i) outcomes[i].id = tasks[i].id;
    job_ids_.clear();
    if (tasks.empty()) return outcomes;
    // Ends task i with `o`; `record`: the executor writes outcome.json (the task's script
    // wrote none).
    const auto finish = [&](std::size_t i, TaskOutcome o, bool record) {
      o.id = tasks[i].id;
      if (record) Record(tasks[i], o);
      outcomes[i] = std::move(o);
      done[i] = true;
      if (on_done) on_done(outcomes[i]);
    };
    const auto fail = [&](std::size_t i, const std::string& error, bool record) {
      TaskOutcome o;
      o.wall_s = std::nan("");
      o.error = error;
      finish(i, o, record);
    };

    fs::path batch;
    try {
      batch = MakeBatchFolder(SlurmStudyOf(tasks.front()) / "slurm");
      std::string lines;
      for (const TrialTask& t : tasks) {
        std::error_code ec;
        fs::remove(SlurmOutcomePath(t), ec);  // a stale one would pass for this run's
        fs::create_directories(t.log.parent_path(), ec);
        std::string line = SlurmShellQuote(t.id) + " " + SlurmShellQuote(SlurmJsonString(t.id));
        for (const fs::path& p : {t.request, t.result, t.log, SlurmOutcomePath(t)})
          line += " " + SlurmShellQuote(fs::absolute(p).string());
        for (const std::string& a : TrialCommand(o_.echoservo_exe, t))
          line += " " + SlurmShellQuote(a);
        lines += line + "\n";
      }
      formats::ReplaceFileContents(batch / "tasks.txt", lines);
      formats::ReplaceFileContents(batch / "job.sh", SlurmJobScript(batch, o_.timeout_s));
      fs::permissions(batch / "job.sh", fs::perms::owner_all | fs::perms::group_read |
                                            fs::perms::group_exec | fs::perms::others_read |
                                            fs::perms::others_exec);
    } catch (const std::exception& e) {
      for (std::size_t i = 0; i < tasks.size(); ++i)
        fail(i, std::string("cannot write the Slurm batch files: ") + e.what(), true);
      return outcomes;
    }

    InterruptGuard guard;
    const std::size_t chunk = static_cast<std::size_t>(SlurmMaxArraySize(o_, batch));
    for (std::size_t begin = 0; begin < tasks.size() && InterruptGuard::signal() == 0;
         begin += chunk) {
      RunChunk(tasks, begin, std::min(tasks.size(), begin + chunk), batch, finish, fail, done);
    }
    if (InterruptGuard::signal() != 0) {
      const std::string why = std::string("interrupted: the study received ") +
                              (InterruptGuard::signal() == SIGINT ? "SIGINT" : "SIGTERM") +
                              "; the Slurm job was cancelled";
      for (std::size_t i = 0; i < tasks.size(); ++i)
        if (!done[i]) fail(i, why, false);  // unfinished: the study reruns it
    }
    return outcomes;
  }

  std::string name() const override {
    std::string n = "slurm";
    if (!job_ids_.empty()) {
      n += job_ids_.size() == 1 ? " (job " : " (jobs ";
      for (std::size_t i = 0; i < job_ids_.size(); ++i) n += (i ? ", " : "") + job_ids_[i];
      n += ")";
    }
    return n;
  }

 private:
  template <class Finish, class Fail>
  void RunChunk(const std::vector<TrialTask>& tasks, std::size_t begin, std::size_t end,
                const fs::path& batch, const Finish& finish, const Fail& fail,
                std::vector<bool>& done) {
    const std::string stem = "sbatch-" + std::to_string(begin);
    std::vector<std::string> argv = {o_.sbatch, "--wait", "--parsable"};
    std::string array = "--array=0-" + std::to_string(end - begin - 1);
    if (o_.max_parallel > 0) array += "%" + std::to_string(o_.max_parallel);
    argv.push_back(array);
    if (!o_.partition.empty()) argv.push_back("--partition=" + o_.partition);
    const int minutes = static_cast<int>(std::ceil((o_.timeout_s + kSlurmKillAfterS + 30) / 60));
    argv.push_back("--time=" + std::to_string(minutes));
    argv.push_back("--job-name=echoservo-tune");
    argv.push_back("--chdir=" + batch.string());
    argv.push_back("--output=/dev/null");
    argv.push_back("--export=ALL");
    for (const auto& a : o_.extra_args) argv.push_back(a);
    argv.push_back((batch / "job.sh").string());
    argv.push_back(std::to_string(begin));

    std::string spawn_error;
    const pid_t pid = SlurmSpawn(argv, batch, stem, true, spawn_error);
    if (pid < 0) {
      for (std::size_t i = begin; i < end; ++i)
        fail(i, "sbatch refused the job: " + spawn_error, true);
      return;
    }
    // Outcomes are taken as their files appear (on_done in completion order); sbatch --wait
    // returning says the array has ended.
    const std::size_t n = end - begin;
    const auto poll = std::chrono::milliseconds(std::min<std::size_t>(1000, 100 + n));
    const auto take_outcomes = [&] {
      std::size_t left = 0;
      for (std::size_t i = begin; i < end; ++i) {
        if (done[i]) continue;
        const std::optional<TaskOutcome> o = ReadOutcome(tasks[i]);
        if (o) {
          finish(i, *o, false);
        } else {
          ++left;
        }
      }
      return left;
    };
    int wstatus = 0;
    bool ended = false;
    std::string queued_id;  // the job id, once sbatch has printed it
    auto next_queue_check = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
    while (!ended) {
      ended = SlurmWait(pid, true, wstatus);
      const std::size_t left = take_outcomes();
      if (InterruptGuard::signal() != 0) break;
      bool over = left == 0;  // every task has written its outcome
      // sbatch --wait polls every 2 s or more (up to 32 s): squeue says sooner that the
      // array has left the queue (tasks that ended without an outcome included).
      if (!ended && !over && std::chrono::steady_clock::now() >= next_queue_check) {
        if (queued_id.empty()) queued_id = SlurmJobId(SlurmReadFile(batch / (stem + ".out")));
        if (!queued_id.empty()) over = SlurmLeftQueue(o_, queued_id, batch);
        next_queue_check = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
      }
      if (over && !ended) {
        // The array is over but for Slurm's bookkeeping: sbatch need not see it.
        ::kill(pid, SIGTERM);
        ended = SlurmWait(pid, false, wstatus);
        take_outcomes();
      }
      if (!ended) std::this_thread::sleep_for(poll);
    }
    const std::string job_id = SlurmJobId(SlurmReadFile(batch / (stem + ".out")));
    if (!job_id.empty()) job_ids_.push_back(job_id);
    if (InterruptGuard::signal() != 0) {
      if (!job_id.empty())
        SlurmRunCommand({SlurmSibling(o_.sbatch, "scancel"), job_id}, batch, "scancel");
      ::kill(pid, SIGTERM);
      SlurmWait(pid, false, wstatus);
      return;
    }
    const SlurmCommandResult r = SlurmCollect(o_.sbatch, wstatus, batch, stem);
    if (job_id.empty()) {
      std::string why = r.spawn_error;
      if (why.empty()) why = SlurmTrim(r.err);
      if (why.empty()) why = SlurmTrim(r.out);
      if (why.empty()) {
        why = r.signal != 0 ? "ended by signal " + std::to_string(r.signal)
                            : "exit status " + std::to_string(r.status);
      }
      for (std::size_t i = begin; i < end; ++i)
        if (!done[i]) fail(i, "sbatch refused the job: " + why, true);
      return;
    }
    if (take_outcomes() == 0) return;
    // Tasks without an outcome: Slurm says why. A task that completed has written one
    // (job.sh exits 0 only then): a shared file system may show it a little later.
    std::map<int, std::string> states = SlurmTaskStates(o_, job_id, batch);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    const auto completed = [&] {
      for (std::size_t i = begin; i < end; ++i) {
        const auto it = states.find(static_cast<int>(i - begin));
        if (!done[i] && it != states.end() && it->second.rfind("COMPLETED", 0) == 0) return true;
      }
      return false;
    };
    while (completed() && std::chrono::steady_clock::now() < deadline && take_outcomes() > 0)
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    for (std::size_t i = begin; i < end; ++i) {
      if (done[i]) continue;
      const auto it = states.find(static_cast<int>(i - begin));
      const std::string state = it != states.end() && !it->second.empty()
                                    ? it->second
                                    : std::string("unknown: sacct and scontrol have no record");
      fail(i,
           "no outcome written (Slurm state: " + state + "; job " + job_id + "_" +
               std::to_string(i - begin) + ")",
           true);
    }
  }

  // The outcome.json the task's script wrote, once it is there and whole.
  static std::optional<TaskOutcome> ReadOutcome(const TrialTask& t) {
    const fs::path path = SlurmOutcomePath(t);
    std::error_code ec;
    if (!fs::exists(path, ec)) return std::nullopt;
    try {
      TaskOutcome o = TaskOutcomeFromJson(SlurmReadFile(path), path.string());
      if (o.id != t.id) return std::nullopt;
      return o;
    } catch (const std::exception&) {
      return std::nullopt;
    }
  }

  // STUDY/slurm/batch-0001, -0002, ...: a new folder per Run (an adaptive search runs several).
  static fs::path MakeBatchFolder(const fs::path& root) {
    fs::create_directories(root);
    for (int n = 1; n < 1000000; ++n) {
      char name[32];
      std::snprintf(name, sizeof name, "batch-%04d", n);
      const fs::path p = root / name;
      if (fs::create_directory(p)) return fs::absolute(p);
    }
    throw std::runtime_error(root.string() + ": no free batch folder name");
  }

  // An outcome the executor made itself (the task's script wrote none), beside the trial's.
  static void Record(const TrialTask& t, const TaskOutcome& o) {
    try {
      formats::ReplaceFileContents(SlurmOutcomePath(t), TaskOutcomeToJson(o));
    } catch (const std::exception&) {
      // The outcome is still returned; the study records the trial's failure.
    }
  }

  SlurmExecutorOptions o_;
  std::vector<std::string> job_ids_;
};

}  // namespace

std::unique_ptr<TrialExecutor> MakeSlurmExecutor(const SlurmExecutorOptions& o) {
  const auto bad = [](const std::string& why) {
    throw std::invalid_argument("Slurm executor: " + why);
  };
  if (o.echoservo_exe.empty()) bad("echoservo_exe is empty");
  if (o.sbatch.empty()) bad("sbatch is empty");
  if (!(o.timeout_s > 0.0 && o.timeout_s <= 7 * 86400.0))
    bad("timeout_s must be in (0, 604800] s, got " + std::to_string(o.timeout_s));
  if (o.max_parallel < 0) bad("max_parallel must be >= 0, got " + std::to_string(o.max_parallel));
  for (const char c : o.partition) {
    if (std::isspace(static_cast<unsigned char>(c)) || c == '\0' || c == '\'' || c == '"')
      bad("partition '" + o.partition + "' is not a partition name");
  }
  for (const std::string& a : o.extra_args) {
    if (a.empty()) bad("an empty extra sbatch argument");
    for (const char* own : {"--wait", "--parsable", "--array", "--output", "--chdir"}) {
      if (a.rfind(own, 0) == 0)
        bad("extra sbatch argument '" + a + "': the executor sets " + std::string(own) + " itself");
    }
  }
  return std::make_unique<SlurmExecutor>(o);
}

}  // namespace echoservo::tune
