// RunStudy (tune/study.h). Which trials a rerun runs again: a trial is finished when its
// result.json reads back and is either "ok" or a failure the trial process itself reported
// (bad input: deterministic, rerunning cannot change it). A failure the study wrote for a
// process that ended without a result (crashed, killed, timed out, could not start, exited
// without writing one) starts with kStudyReasonPrefix: that trial is run again, as is one
// interrupted by Ctrl-C (no result at all).
#include "tune/study.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <ctime>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "tune/search.h"

namespace echoservo::tune {
namespace {

namespace study_fs = std::filesystem;

// The reason of every failed result the study writes (not the trial process): rerun.
constexpr const char* kStudyReasonPrefix = "trial process: ";
// The error a local executor gives a trial it interrupted (tune/local_executor.cc).
constexpr const char* kStudyInterruptedPrefix = "interrupted: ";

bool StudyStartsWith(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

std::string StudyUtcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string StudySignalName(int sig) {
  switch (sig) {
    case SIGSEGV:
      return "SIGSEGV";
    case SIGABRT:
      return "SIGABRT";
    case SIGKILL:
      return "SIGKILL";
    case SIGTERM:
      return "SIGTERM";
    case SIGINT:
      return "SIGINT";
    case SIGBUS:
      return "SIGBUS";
    case SIGFPE:
      return "SIGFPE";
    case SIGILL:
      return "SIGILL";
    case SIGHUP:
      return "SIGHUP";
    case SIGPIPE:
      return "SIGPIPE";
    case SIGXCPU:
      return "SIGXCPU";
    default:
      return "signal " + std::to_string(sig);
  }
}

std::string StudyNumber(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

// The last non-empty line of a trial's log, shortened: the trial's own last word.
std::string StudyLastLogLine(const study_fs::path& log) {
  std::ifstream in(log);
  std::string line, last;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] != '$') last = line;
  }
  if (last.size() > 300) last = last.substr(0, 300) + "…";
  return last;
}

// Why a process ended without a result, for the failed result the study writes.
std::string StudyFailureReason(const TaskOutcome& o, const study_fs::path& log, double timeout_s,
                               const std::string& result_problem) {
  std::string why;
  if (!o.error.empty()) {
    why = o.error;
  } else if (o.timed_out) {
    why = "timed out (limit " + StudyNumber(timeout_s) + " s, ran " + StudyNumber(o.wall_s) + " s" +
          (o.signal != 0 ? ", ended by " + StudySignalName(o.signal) : "") + ")";
  } else if (o.signal != 0) {
    why = "killed by " + StudySignalName(o.signal) + " (signal " + std::to_string(o.signal) + ")";
  } else {
    why = "exited with status " + std::to_string(o.exit_code) + " without writing result.json";
  }
  if (!result_problem.empty()) why += "; " + result_problem;
  const std::string last = StudyLastLogLine(log);
  if (!last.empty() && o.error.empty()) why += "; last log line: " + last;
  return kStudyReasonPrefix + why;
}

bool StudyFinished(const std::optional<TrialResult>& r) {
  return r.has_value() && !(r->status != "ok" && StudyStartsWith(r->reason, kStudyReasonPrefix));
}

// An exclusive lock on STUDY/.lock for the study's lifetime: two studies writing one
// folder at once would run trials twice.
class StudyLock {
 public:
  explicit StudyLock(const study_fs::path& study) {
    const study_fs::path path = study / ".lock";
    fd_ = open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) throw std::runtime_error(path.string() + ": cannot be created");
    if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      close(fd_);
      throw std::invalid_argument(study.string() +
                                  ": another `echoservo tune` is running this STUDY");
    }
  }
  ~StudyLock() {
    if (fd_ >= 0) close(fd_);
  }
  StudyLock(const StudyLock&) = delete;
  StudyLock& operator=(const StudyLock&) = delete;

 private:
  int fd_ = -1;
};

class StudyRunner {
 public:
  StudyRunner(const StudySpec& spec, const study_fs::path& study, TrialExecutor& executor,
              const std::function<void(const std::string&)>& log)
      : spec_(spec), study_(study), executor_(executor), log_(log) {}

  StudySummary Run() {
    const auto start = std::chrono::steady_clock::now();
    PrepareFolder();
    StudyLock lock(study_);
    LoadExisting();
    Log("study " + study_.string() + ": " + std::to_string(spec_.recordings.size()) +
        " recording(s), objective " + spec_.metric + " (" +
        (spec_.minimize ? "minimize" : "maximize") + "), " + spec_.method + " search, on " +
        executor_.name());

    const int base = SetFor(spec_.fixed, true);
    if (spec_.method == "adaptive") {
      RunSets({base});
      RunAdaptive();
    } else {
      std::vector<int> sets{base};
      const std::vector<AxisValues> proposals =
          spec_.method == "grid" ? GridProposals(spec_.axes)
                                 : RandomProposals(spec_.axes, spec_.trials, spec_.seed);
      for (const AxisValues& x : proposals) {
        const int s = SetFor(SettingsOf(x));
        if (std::find(sets.begin(), sets.end(), s) == sets.end()) sets.push_back(s);
      }
      if (spec_.method == "random" && static_cast<int>(proposals.size()) < spec_.trials) {
        Log("random search: the space holds " + std::to_string(proposals.size()) +
            " distinct sets, fewer than the " + std::to_string(spec_.trials) + " asked");
      }
      RunSets(sets);
    }

    summary_.sets = sets_used_.size();
    summary_.trials = summary_.sets * spec_.recordings.size();
    for (int s : sets_used_) {
      for (std::size_t r = 0; r < spec_.recordings.size(); ++r) {
        const auto it = results_.find(TrialId(s, static_cast<int>(r)));
        if (it != results_.end() && it->second.status != "ok") ++summary_.failed;
      }
    }
    summary_.wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    LogBest();
    return summary_;
  }

 private:
  void Log(const std::string& line) const {
    if (log_) log_(line);
  }

  void PrepareFolder() {
    std::error_code ec;
    const study_fs::path header = study_ / "study.json";
    if (study_fs::exists(header, ec)) {
      const StudyHeader h = ReadStudyHeader(study_);
      if (h.spec_json != spec_.normalised_json) {
        const nlohmann::json a = nlohmann::json::parse(h.spec_json, nullptr, false);
        const nlohmann::json b = nlohmann::json::parse(spec_.normalised_json, nullptr, false);
        std::string where;
        if (!a.is_discarded() && !b.is_discarded()) {
          std::set<std::string> paths;
          for (const auto& op : nlohmann::json::diff(a, b))
            paths.insert(op["path"].get<std::string>());
          int shown = 0;
          for (const std::string& p : paths) {
            if (shown++ == 6) {
              where += ", …";
              break;
            }
            where += (where.empty() ? "" : ", ") + p;
          }
        }
        throw std::invalid_argument(
            study_.string() + " was made by a different SPEC (" +
            (h.spec_path.empty() ? std::string("see its study.json") : h.spec_path) +
            "); they differ at " + (where.empty() ? std::string("?") : where) +
            ": give a new --out folder, or run the SPEC the study was made with");
      }
      return;
    }
    if (study_fs::exists(study_, ec)) {
      if (!study_fs::is_directory(study_, ec))
        throw std::invalid_argument(study_.string() + ": exists and is not a folder");
      if (!study_fs::is_empty(study_, ec)) {
        throw std::invalid_argument(study_.string() +
                                    ": a folder that is not empty and has no study.json (not a "
                                    "STUDY): give a new or empty --out folder");
      }
    }
    study_fs::create_directories(study_, ec);
    if (ec)
      throw std::runtime_error(study_.string() + ": cannot be created (" + ec.message() + ")");
    StudyHeader h;
    h.spec_json = spec_.normalised_json;
    h.objective = spec_.metric;
    h.minimize = spec_.minimize;
    h.search = spec_.method;
    for (const ParameterAxis& a : spec_.axes) h.parameters.push_back(a.name);
    for (const RecordingSpec& r : spec_.recordings) {
      h.recordings.push_back(r.path);
      h.recording_names.push_back(r.name);
      h.em_logs.push_back(!r.em_log.empty() ? r.em_log : r.info.em_log);
    }
    h.created_utc = StudyUtcNow();
    h.spec_path = spec_path_;
    WriteStudyHeader(study_, h);
  }

  // Every trial already in the STUDY: its set (by the tuned values) and its result.
  void LoadExisting() {
    std::vector<std::string> problems;
    for (StudyTrial& t : ReadTrials(study_, &problems)) {
      next_set_ = std::max(next_set_, t.set_index + 1);
      if (t.recording_index < 0 || t.recording_index >= static_cast<int>(spec_.recordings.size()) ||
          t.request.recording !=
              spec_.recordings[static_cast<std::size_t>(t.recording_index)].path) {
        problems.push_back("trial " + t.id + " is not one of this SPEC's recordings: ignored");
        continue;
      }
      const AxisValues key = KeyOf(t.request.settings);
      const auto known = key_to_set_.find(key);
      if (known == key_to_set_.end()) {
        key_to_set_[key] = t.set_index;
        set_settings_[t.set_index] = t.request.settings;
      } else if (known->second != t.set_index) {
        problems.push_back("trial " + t.id + " repeats set " + std::to_string(known->second) +
                           ": ignored");
        continue;
      }
      if (t.result) results_[t.id] = *t.result;
    }
    for (const std::string& p : problems) Log("warning: " + p);
  }

  // The tuned values a list of assignments gives (the registry's defaults where absent).
  AxisValues KeyOf(const std::vector<live::Assignment>& settings) const {
    AxisValues key;
    for (const ParameterAxis& a : spec_.axes) {
      double v = std::numeric_limits<double>::quiet_NaN();
      if (const live::ParameterInfo* p = live::FindParameter(a.name)) v = p->default_value;
      for (const live::Assignment& s : settings) {
        if (s.first == a.name) v = s.second;
      }
      key.push_back(v);
    }
    return key;
  }

  std::vector<live::Assignment> SettingsOf(const AxisValues& x) const {
    std::vector<live::Assignment> settings = spec_.fixed;
    for (std::size_t i = 0; i < spec_.axes.size(); ++i)
      settings.emplace_back(spec_.axes[i].name, x[i]);
    return settings;
  }

  // The set with these tuned values: one already in the STUDY, or a new index.
  int SetFor(const std::vector<live::Assignment>& settings, bool base = false) {
    const AxisValues key = KeyOf(settings);
    auto it = key_to_set_.find(key);
    int s = 0;
    if (it != key_to_set_.end()) {
      s = it->second;
    } else {
      s = base && set_settings_.count(0) == 0 ? 0 : std::max(next_set_, 1);
      next_set_ = s + 1;
      key_to_set_[key] = s;
      set_settings_[s] = settings;
    }
    if (std::find(sets_used_.begin(), sets_used_.end(), s) == sets_used_.end())
      sets_used_.push_back(s);
    return s;
  }

  std::string Describe(int set) const {
    const auto it = set_settings_.find(set);
    std::string text;
    if (it != set_settings_.end()) {
      for (const live::Assignment& a : it->second) {
        bool tuned = false;
        for (const ParameterAxis& ax : spec_.axes) tuned = tuned || ax.name == a.first;
        if (tuned) text += (text.empty() ? "" : " ") + live::FormatAssignment(a);
      }
    }
    return text.empty() ? std::string("defaults") : text;
  }

  TrialRequest RequestFor(int set, std::size_t r) const {
    TrialRequest q;
    const RecordingSpec& rec = spec_.recordings[r];
    q.recording = rec.path;
    q.em_log = rec.em_log;
    q.settings = set_settings_.at(set);
    q.latency_s = spec_.latency_s;
    q.delay_s = spec_.delay_s;
    q.from_s = spec_.from_s;
    q.loop = spec_.loop;
    return q;
  }

  // Runs every unfinished trial of `sets` on the executor, in one batch.
  void RunSets(const std::vector<int>& sets) {
    std::vector<TrialTask> tasks;
    for (int s : sets) {
      for (std::size_t r = 0; r < spec_.recordings.size(); ++r) {
        const std::string id = TrialId(s, static_cast<int>(r));
        const auto done = results_.find(id);
        if (done != results_.end() && StudyFinished(done->second)) {
          if (considered_.insert(id).second) ++summary_.skipped;
          continue;
        }
        considered_.insert(id);
        const study_fs::path dir = TrialDir(study_, id);
        std::error_code ec;
        study_fs::remove(dir / "result.json", ec);  // a retried failure's stale result
        study_fs::remove(dir / "outcome.json", ec);
        results_.erase(id);
        StudyTrial t;
        t.id = id;
        t.set_index = s;
        t.recording_index = static_cast<int>(r);
        t.request = RequestFor(s, r);
        WriteTrialRequest(study_, t);
        tasks.push_back({id, dir / "request.json", dir / "result.json", dir / "log.txt"});
      }
    }
    if (tasks.empty()) return;
    std::size_t ended = 0, interrupted = 0;
    std::string interrupt_why;
    const std::size_t total = tasks.size();
    auto on_done = [&](const TaskOutcome& o) {
      ++ended;
      const study_fs::path dir = TrialDir(study_, o.id);
      std::optional<TrialResult> result;
      std::string problem;
      std::error_code ec;
      if (study_fs::exists(dir / "result.json", ec)) {
        try {
          std::ifstream in(dir / "result.json", std::ios::binary);
          std::ostringstream text;
          text << in.rdbuf();
          result = ResultFromJson(text.str(), (dir / "result.json").string());
        } catch (const std::exception& e) {
          problem = std::string("its result.json is unreadable: ") + e.what();
        }
      }
      if (!result && StudyStartsWith(o.error, kStudyInterruptedPrefix)) {
        ++interrupted;
        interrupt_why = o.error;
        return;  // unfinished: a rerun runs it
      }
      ++summary_.ran;
      if (!result) {
        TrialResult failed;
        failed.status = "failed";
        failed.reason = StudyFailureReason(o, dir / "log.txt", timeout_s_, problem);
        try {
          WriteTrialResult(study_, o.id, failed);
        } catch (const std::exception& e) {
          Log("warning: " + o.id + ": " + e.what());
        }
        result = failed;
      }
      results_[o.id] = *result;
      std::string line = "[" + std::to_string(ended) + "/" + std::to_string(total) + "] " + o.id;
      if (result->status == "ok") {
        const auto m = result->metrics.find(spec_.metric);
        line += " ok " + spec_.metric + "=" +
                (m != result->metrics.end() ? StudyNumber(m->second) : std::string("n/a"));
      } else {
        line += " FAILED: " + result->reason;
      }
      if (std::isfinite(o.wall_s)) line += " (" + StudyNumber(o.wall_s) + " s)";
      Log(line);
    };
    executor_.Run(tasks, on_done);
    if (interrupted > 0) {
      throw std::runtime_error(interrupt_why.substr(0, interrupt_why.find(" before")) + ": " +
                               std::to_string(interrupted) +
                               " trial(s) left unfinished; every finished trial is kept in " +
                               study_.string() + ": rerun the same command to resume");
    }
  }

  // The set's objective: the mean over the recordings; NaN unless every trial gave it.
  double SetMean(int set) const {
    double sum = 0.0;
    for (std::size_t r = 0; r < spec_.recordings.size(); ++r) {
      const auto it = results_.find(TrialId(set, static_cast<int>(r)));
      if (it == results_.end() || it->second.status != "ok")
        return std::numeric_limits<double>::quiet_NaN();
      const auto m = it->second.metrics.find(spec_.metric);
      if (m == it->second.metrics.end() || !std::isfinite(m->second))
        return std::numeric_limits<double>::quiet_NaN();
      sum += m->second;
    }
    return sum / static_cast<double>(spec_.recordings.size());
  }

  void RunAdaptive() {
    AdaptiveOptions ao;
    ao.max_evaluations = spec_.trials;
    ao.seed = spec_.seed;
    ao.start = KeyOf(spec_.fixed);  // the defaults: BOBYQA starts from the baseline
    for (std::size_t i = 0; i < spec_.axes.size(); ++i) {
      if (!std::isfinite(ao.start[i])) ao.start[i] = 0.5 * (spec_.axes[i].min + spec_.axes[i].max);
    }
    int evaluation = 0;
    const AdaptiveResult r = AdaptiveSearch(spec_.axes, ao, [&](const AxisValues& x) {
      const int set = SetFor(SettingsOf(x));
      RunSets({set});
      const double mean = SetMean(set);
      ++evaluation;
      Log("adaptive " + std::to_string(evaluation) + "/" + std::to_string(spec_.trials) + ": set " +
          std::to_string(set) + " (" + Describe(set) + "): mean " + spec_.metric + " " +
          (std::isfinite(mean) ? StudyNumber(mean)
                               : std::string("n/a (a trial failed: penalised)")));
      return spec_.minimize ? mean : -mean;
    });
    Log("adaptive search (BOBYQA): " + r.stop_reason + " after " + std::to_string(r.evaluations) +
        " evaluations");
  }

  void LogBest() const {
    int best = -1;
    double best_mean = 0.0;
    for (int s : sets_used_) {
      const double m = SetMean(s);
      if (!std::isfinite(m)) continue;
      if (best < 0 || (spec_.minimize ? m < best_mean : m > best_mean)) {
        best = s;
        best_mean = m;
      }
    }
    if (best < 0) {
      Log("no set finished on every recording");
      return;
    }
    const double base = SetMean(0);
    Log("best: set " + std::to_string(best) + " (" + Describe(best) + "): mean " + spec_.metric +
        " " + StudyNumber(best_mean) + " over " + std::to_string(spec_.recordings.size()) +
        " recording(s); defaults (set 0): " +
        (std::isfinite(base) ? StudyNumber(base) : std::string("n/a")) +
        ". Confidence intervals and per-recording results: echoservo tune report " +
        study_.string() + " --out study.html");
  }

 public:
  std::string spec_path_;
  double timeout_s_ = 0.0;

 private:
  const StudySpec& spec_;
  study_fs::path study_;
  TrialExecutor& executor_;
  std::function<void(const std::string&)> log_;
  StudySummary summary_;
  std::map<AxisValues, int> key_to_set_;
  std::map<int, std::vector<live::Assignment>> set_settings_;
  std::map<std::string, TrialResult> results_;
  std::set<std::string> considered_;
  std::vector<int> sets_used_;
  int next_set_ = 0;
};

}  // namespace

StudySummary RunStudy(const StudySpec& spec, const std::filesystem::path& study,
                      TrialExecutor& executor, const std::function<void(const std::string&)>& log) {
  if (study.empty()) throw std::invalid_argument("RunStudy: no STUDY folder (--out)");
  if (spec.recordings.empty()) throw std::invalid_argument("RunStudy: the SPEC has no recording");
  StudyRunner runner(spec, study_fs::absolute(study).lexically_normal(), executor, log);
  runner.timeout_s_ = spec.timeout_s;
  runner.spec_path_ = spec.path;
  return runner.Run();
}

}  // namespace echoservo::tune
