// The local executor (tune/executor.h): trial processes on this machine, up to `jobs` at
// once, each started with posix_spawn in a process group of its own (so that a timeout or
// an interrupt reaches everything it started), stdin from /dev/null, stdout and stderr to
// its log file, killed after timeout_s (SIGTERM to its group, SIGKILL kLocalKillGraceS
// later).
// Cores: with more than one job, each trial is bound (sched_setaffinity, inherited through
// posix_spawn) to its job slot's share of the cores available, so that a trial's
// multi-threaded stages (the detector's TBB) use its share instead of every trial spreading
// threads over all the cores. One job: unbound.
// Ctrl-C: SIGINT or SIGTERM to the study while Run is active (Ctrl-C in a terminal reaches
// only the study: the trials are in groups of their own) is forwarded to every running
// trial's group; no new trial starts; Run waits for them (SIGKILL after the grace, or at once
// on a second signal) and returns. Their outcomes carry the error "interrupted: …"
// (kLocalInterruptedPrefix), as do the tasks that never started: the study (tune/study.cc)
// treats them as unfinished, so a rerun runs them.
#include <fcntl.h>
#include <sched.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "tune/executor.h"
#include "tune/interrupt.h"

extern char** environ;

namespace echoservo::tune {
namespace {

constexpr double kLocalKillGraceS = 3.0;
constexpr auto kLocalPoll = std::chrono::milliseconds(5);
constexpr const char* kLocalInterruptedPrefix = "interrupted: ";

std::string LocalSignalName(int sig) {
  switch (sig) {
    case SIGHUP:
      return "SIGHUP";
    case SIGINT:
      return "SIGINT";
    case SIGQUIT:
      return "SIGQUIT";
    case SIGILL:
      return "SIGILL";
    case SIGABRT:
      return "SIGABRT";
    case SIGBUS:
      return "SIGBUS";
    case SIGFPE:
      return "SIGFPE";
    case SIGKILL:
      return "SIGKILL";
    case SIGSEGV:
      return "SIGSEGV";
    case SIGPIPE:
      return "SIGPIPE";
    case SIGALRM:
      return "SIGALRM";
    case SIGTERM:
      return "SIGTERM";
    case SIGXCPU:
      return "SIGXCPU";
    default:
      return "signal " + std::to_string(sig);
  }
}

// The CPUs this thread may run on (empty when unknown).
std::vector<int> LocalAllowedCpus() {
  std::vector<int> cpus;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) {
    for (int c = 0; c < CPU_SETSIZE; ++c) {
      if (CPU_ISSET(c, &set)) cpus.push_back(c);
    }
  }
  return cpus;
}

int LocalAvailableCores() {
  const std::size_t n = LocalAllowedCpus().size();
  if (n > 0) return static_cast<int>(n);
  const unsigned h = std::thread::hardware_concurrency();
  return h > 0 ? static_cast<int>(h) : 1;
}

// Binds the calling thread to `cpus` for its lifetime (a child spawned meanwhile inherits
// the binding), then restores the previous mask. Does nothing for an empty list.
class LocalCpuBinding {
 public:
  explicit LocalCpuBinding(const std::vector<int>& cpus) {
    if (cpus.empty() || sched_getaffinity(0, sizeof old_, &old_) != 0) return;
    cpu_set_t set;
    CPU_ZERO(&set);
    for (int c : cpus) CPU_SET(c, &set);
    bound_ = sched_setaffinity(0, sizeof set, &set) == 0;
  }
  ~LocalCpuBinding() {
    if (bound_) sched_setaffinity(0, sizeof old_, &old_);
  }
  LocalCpuBinding(const LocalCpuBinding&) = delete;
  LocalCpuBinding& operator=(const LocalCpuBinding&) = delete;

 private:
  cpu_set_t old_{};
  bool bound_ = false;
};

// The STUDY folder of a task laid out as tune/study_files.h says (STUDY/trials/<id>/…);
// empty when it is not.
std::filesystem::path LocalStudyOf(const TrialTask& t) {
  const std::filesystem::path dir = t.request.parent_path();
  if (dir.filename() != t.id || dir.parent_path().filename() != "trials") return {};
  return dir.parent_path().parent_path();
}

class LocalExecutor final : public TrialExecutor {
 public:
  explicit LocalExecutor(const LocalExecutorOptions& o) : o_(o) {
    if (o_.echoservo_exe.empty())
      throw std::invalid_argument("local executor: no program to start (echoservo_exe)");
    if (o_.jobs < 0 || o_.jobs > 4096)
      throw std::invalid_argument("local executor: jobs " + std::to_string(o_.jobs) +
                                  " outside [0, 4096] (0: the cores available)");
    if (!(o_.timeout_s > 0.0 && o_.timeout_s <= 86400.0))
      throw std::invalid_argument("local executor: timeout " + std::to_string(o_.timeout_s) +
                                  " s outside (0, 86400] s");
    jobs_ = o_.jobs > 0 ? o_.jobs : LocalAvailableCores();
  }

  std::string name() const override {
    return "local (" + std::to_string(jobs_) + (jobs_ == 1 ? " job)" : " jobs)");
  }

  std::vector<TaskOutcome> Run(const std::vector<TrialTask>& tasks,
                               const std::function<void(const TaskOutcome&)>& on_done) override {
    using Clock = std::chrono::steady_clock;
    struct Running {
      std::size_t index = 0;
      int slot = 0;
      pid_t pid = -1;
      Clock::time_point start, term_at;
      bool term_sent = false, kill_sent = false, timed_out = false, interrupted = false;
    };
    std::vector<TaskOutcome> outcomes(tasks.size());
    std::vector<Running> running;
    std::vector<bool> slot_busy(static_cast<std::size_t>(jobs_), false);
    const std::vector<int> cpus = LocalAllowedCpus();
    InterruptGuard guard;
    int interrupt = 0;
    int signals_at_interrupt = 0;
    std::size_t next = 0;

    auto finish = [&](std::size_t index, TaskOutcome o) {
      const std::filesystem::path study = LocalStudyOf(tasks[index]);
      if (!study.empty()) {
        try {
          WriteTaskOutcome(study, o);
        } catch (const std::exception& e) {
          o.error +=
              std::string(o.error.empty() ? "" : "; ") + "outcome.json not written: " + e.what();
        }
      }
      outcomes[index] = o;
      if (on_done) on_done(outcomes[index]);
    };
    auto interrupted_error = [&] {
      return std::string(kLocalInterruptedPrefix) + "the study received " +
             LocalSignalName(interrupt);
    };

    while (next < tasks.size() || !running.empty()) {
      // An interrupt: forward it to every running trial, start nothing more.
      if (InterruptGuard::signal() != 0 && interrupt == 0) {
        interrupt = InterruptGuard::signal();
        signals_at_interrupt = InterruptGuard::count();
        for (Running& r : running) {
          kill(-r.pid, interrupt);
          r.interrupted = true;
          r.term_sent = true;
          r.term_at = Clock::now();
        }
        for (; next < tasks.size(); ++next) {
          TaskOutcome o;
          o.id = tasks[next].id;
          o.error = interrupted_error() + " before this trial started";
          outcomes[next] = o;  // nothing happened: no outcome.json
          if (on_done) on_done(outcomes[next]);
        }
      }
      if (interrupt != 0 && InterruptGuard::count() > signals_at_interrupt) {
        for (Running& r : running) {  // a second signal: no more grace
          if (!r.kill_sent) kill(-r.pid, SIGKILL);
          r.kill_sent = true;
        }
      }

      while (interrupt == 0 && running.size() < static_cast<std::size_t>(jobs_) &&
             next < tasks.size()) {
        const std::size_t index = next++;
        TaskOutcome o;
        o.id = tasks[index].id;
        const int slot = static_cast<int>(std::find(slot_busy.begin(), slot_busy.end(), false) -
                                          slot_busy.begin());
        const pid_t pid = Start(tasks[index], SlotCpus(cpus, slot), o.error);
        if (pid < 0) {
          finish(index, o);
          continue;
        }
        Running r;
        r.index = index;
        r.slot = slot;
        slot_busy[static_cast<std::size_t>(slot)] = true;
        r.pid = pid;
        r.start = Clock::now();
        running.push_back(r);
      }

      const Clock::time_point now = Clock::now();
      for (std::size_t k = 0; k < running.size();) {
        Running& r = running[k];
        int status = 0;
        const pid_t w = waitpid(r.pid, &status, WNOHANG);
        if (w == r.pid || (w < 0 && errno == ECHILD)) {
          // The trial may have left processes in its group behind: end them.
          kill(-r.pid, SIGKILL);
          TaskOutcome o;
          o.id = tasks[r.index].id;
          o.wall_s = std::chrono::duration<double>(Clock::now() - r.start).count();
          o.timed_out = r.timed_out;
          if (w == r.pid && WIFEXITED(status)) o.exit_code = WEXITSTATUS(status);
          if (w == r.pid && WIFSIGNALED(status)) o.signal = WTERMSIG(status);
          if (w < 0) o.error = "lost track of the process (waitpid: no such child)";
          if (r.interrupted) o.error = interrupted_error();
          const std::size_t index = r.index;
          slot_busy[static_cast<std::size_t>(r.slot)] = false;
          running.erase(running.begin() + static_cast<std::ptrdiff_t>(k));
          finish(index, o);
          continue;
        }
        const double age_s = std::chrono::duration<double>(now - r.start).count();
        if (!r.term_sent && age_s > o_.timeout_s) {
          kill(-r.pid, SIGTERM);
          r.term_sent = true;
          r.timed_out = true;
          r.term_at = now;
        } else if (r.term_sent && !r.kill_sent &&
                   std::chrono::duration<double>(now - r.term_at).count() > kLocalKillGraceS) {
          kill(-r.pid, SIGKILL);
          r.kill_sent = true;
        }
        ++k;
      }
      if (!running.empty() || next < tasks.size()) std::this_thread::sleep_for(kLocalPoll);
    }
    return outcomes;
  }

 private:
  // The CPUs of job slot `slot`: with one job, none (no binding); else an equal share of
  // `cpus` (at least one; slots beyond the cores share them round-robin).
  std::vector<int> SlotCpus(const std::vector<int>& cpus, int slot) const {
    if (jobs_ <= 1 || cpus.size() < 2) return {};
    const std::size_t per = std::max<std::size_t>(1, cpus.size() / static_cast<std::size_t>(jobs_));
    std::vector<int> mine;
    for (std::size_t k = 0; k < per; ++k)
      mine.push_back(cpus[(static_cast<std::size_t>(slot) * per + k) % cpus.size()]);
    return mine;
  }

  // Starts one trial, bound to `cpus` (none: unbound); -1 (and `error`) when it could not
  // start.
  pid_t Start(const TrialTask& t, const std::vector<int>& cpus, std::string& error) const {
    std::error_code ec;
    if (!t.log.parent_path().empty()) std::filesystem::create_directories(t.log.parent_path(), ec);
    const int log = open(t.log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
    if (log < 0) {
      error = "could not start: cannot open the log " + t.log.string() + " (" +
              std::strerror(errno) + ")";
      return -1;
    }
    const std::vector<std::string> args = TrialCommand(o_.echoservo_exe, t);
    std::string header = "$";
    for (const std::string& a : args) header += " " + a;
    header += "\n";
    if (write(log, header.data(), header.size()) < 0) {
      // The log is a convenience: go on without the header.
    }
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);

    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_adddup2(&actions, log, 1);
    posix_spawn_file_actions_adddup2(&actions, log, 2);
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    sigset_t none, defaults;
    sigemptyset(&none);
    sigemptyset(&defaults);
    for (int sig : {SIGINT, SIGTERM, SIGPIPE, SIGHUP, SIGQUIT}) sigaddset(&defaults, sig);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setsigdefault(&attr, &defaults);
    posix_spawnattr_setpgroup(&attr, 0);
    posix_spawnattr_setflags(
        &attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    pid_t pid = -1;
    int rc = 0;
    {
      LocalCpuBinding binding(cpus);
      rc = posix_spawn(&pid, argv[0], &actions, &attr, argv.data(), environ);
    }
    posix_spawnattr_destroy(&attr);
    posix_spawn_file_actions_destroy(&actions);
    close(log);
    if (rc != 0) {
      error = "could not start " + o_.echoservo_exe + ": " + std::strerror(rc);
      return -1;
    }
    return pid;
  }

  LocalExecutorOptions o_;
  int jobs_ = 1;
};

}  // namespace

std::vector<std::string> TrialCommand(const std::string& echoservo_exe, const TrialTask& t) {
  return {echoservo_exe,      "tune",  "trial",          "--request",
          t.request.string(), "--out", t.result.string()};
}

std::unique_ptr<TrialExecutor> MakeLocalExecutor(const LocalExecutorOptions& o) {
  return std::make_unique<LocalExecutor>(o);
}

}  // namespace echoservo::tune
