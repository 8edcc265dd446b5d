#include "tune/study_files.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <tuple>
#include <utility>

#include "formats/durable_file.h"

namespace echoservo::tune {
namespace {

using Json = nlohmann::json;
namespace fs = std::filesystem;

constexpr const char* kStudyFormat = "echoservo-study";
constexpr int kStudyVersion = 1;

// The whole file; throws std::invalid_argument naming it when it cannot be read.
std::string StudyFilesRead(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument(path.string() + ": cannot be read");
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw std::invalid_argument(path.string() + ": read failed");
  return s.str();
}

Json StudyFilesParseObject(std::string_view text, std::string_view where) {
  Json j = Json::parse(text.begin(), text.end(), nullptr, false);
  if (j.is_discarded()) throw std::invalid_argument(std::string(where) + ": not valid JSON");
  if (!j.is_object()) throw std::invalid_argument(std::string(where) + ": not a JSON object");
  return j;
}

std::string StudyFilesField(std::string_view where, const char* key) {
  return std::string(where) + ": field '" + key + "'";
}

std::string StudyFilesString(const Json& j, std::string_view where, const char* key,
                             bool required) {
  if (!j.contains(key)) {
    if (required) throw std::invalid_argument(StudyFilesField(where, key) + " is missing");
    return {};
  }
  if (!j[key].is_string())
    throw std::invalid_argument(StudyFilesField(where, key) + " must be a string");
  return j[key].get<std::string>();
}

std::vector<std::string> StudyFilesStrings(const Json& j, std::string_view where, const char* key) {
  std::vector<std::string> out;
  if (!j.contains(key)) return out;
  if (!j[key].is_array())
    throw std::invalid_argument(StudyFilesField(where, key) + " must be an array of strings");
  for (const Json& v : j[key]) {
    if (!v.is_string())
      throw std::invalid_argument(StudyFilesField(where, key) + " must be an array of strings");
    out.push_back(v.get<std::string>());
  }
  return out;
}

int StudyFilesInt(const Json& j, std::string_view where, const char* key, bool required,
                  int fallback) {
  if (!j.contains(key)) {
    if (required) throw std::invalid_argument(StudyFilesField(where, key) + " is missing");
    return fallback;
  }
  const Json& v = j[key];
  if (!v.is_number_integer() || v.get<long long>() < std::numeric_limits<int>::min() ||
      v.get<long long>() > std::numeric_limits<int>::max())
    throw std::invalid_argument(StudyFilesField(where, key) + " must be an integer");
  return static_cast<int>(v.get<long long>());
}

void StudyFilesWrite(const fs::path& path, const std::string& text) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (ec) {
    throw std::runtime_error(path.parent_path().string() + ": cannot create the folder (" +
                             ec.message() + ")");
  }
  formats::ReplaceFileContents(path, text + "\n");
}

void StudyFilesCheckId(const std::string& id, const char* what) {
  // An id names a folder under trials/: no separators, nothing that climbs out.
  if (id.empty() || id == "." || id == ".." || id.find('/') != std::string::npos ||
      id.find('\\') != std::string::npos || id.find('\0') != std::string::npos)
    throw std::invalid_argument(std::string(what) + ": '" + id + "' is not a trial id");
}

// Digits from `pos` up to a non-digit: the number, or -1 when none or above int's range.
long long StudyFilesDigits(const std::string& text, std::size_t& pos) {
  long long v = 0;
  const std::size_t start = pos;
  while (pos < text.size() && text[pos] >= '0' && text[pos] <= '9') {
    v = v * 10 + (text[pos] - '0');
    if (v > std::numeric_limits<int>::max()) return -1;
    ++pos;
  }
  return pos == start ? -1 : v;
}

// "s0003-r01" → 3, 1 (TrialId's form, any width); false when not of that form.
bool StudyFilesParseId(const std::string& id, int* set, int* recording) {
  if (id.empty() || id[0] != 's') return false;
  std::size_t pos = 1;
  const long long a = StudyFilesDigits(id, pos);
  if (a < 0 || id.compare(pos, 2, "-r") != 0) return false;
  pos += 2;
  const long long b = StudyFilesDigits(id, pos);
  if (b < 0 || pos != id.size()) return false;
  *set = static_cast<int>(a);
  *recording = static_cast<int>(b);
  return true;
}

}  // namespace

std::string TrialId(int set_index, int recording_index) {
  if (set_index < 0 || recording_index < 0) {
    throw std::invalid_argument("TrialId: negative index (set " + std::to_string(set_index) +
                                ", recording " + std::to_string(recording_index) + ")");
  }
  char buf[64];
  std::snprintf(buf, sizeof buf, "s%04d-r%02d", set_index, recording_index);
  return buf;
}

fs::path TrialDir(const fs::path& study, const std::string& id) {
  StudyFilesCheckId(id, "TrialDir");
  return study / "trials" / id;
}

void WriteStudyHeader(const fs::path& study, const StudyHeader& h) {
  const Json j = {{"format", kStudyFormat},     {"version", kStudyVersion},
                  {"spec_json", h.spec_json},   {"spec_path", h.spec_path},
                  {"objective", h.objective},   {"minimize", h.minimize},
                  {"search", h.search},         {"parameters", h.parameters},
                  {"recordings", h.recordings}, {"recording_names", h.recording_names},
                  {"em_logs", h.em_logs},       {"created_utc", h.created_utc}};
  StudyFilesWrite(study / "study.json", j.dump(2));
}

StudyHeader ReadStudyHeader(const fs::path& study) {
  const fs::path path = study / "study.json";
  std::error_code ec;
  if (!fs::is_directory(study, ec))
    throw std::invalid_argument(study.string() + ": no such STUDY folder");
  if (!fs::is_regular_file(path, ec)) {
    throw std::invalid_argument(study.string() +
                                ": no study.json (not a STUDY folder written by `echoservo "
                                "tune SPEC.json --out STUDY`)");
  }
  const std::string where = path.string();
  const Json j = StudyFilesParseObject(StudyFilesRead(path), where);
  if (StudyFilesString(j, where, "format", true) != kStudyFormat)
    throw std::invalid_argument(where + ": field 'format' is not '" + kStudyFormat + "'");
  const int version = StudyFilesInt(j, where, "version", true, 0);
  if (version != kStudyVersion) {
    throw std::invalid_argument(where + ": version " + std::to_string(version) +
                                " (this program reads version " + std::to_string(kStudyVersion) +
                                ")");
  }
  StudyHeader h;
  h.spec_json = StudyFilesString(j, where, "spec_json", true);
  h.spec_path = StudyFilesString(j, where, "spec_path", false);
  h.objective = StudyFilesString(j, where, "objective", true);
  if (j.contains("minimize")) {
    if (!j["minimize"].is_boolean())
      throw std::invalid_argument(StudyFilesField(where, "minimize") + " must be true or false");
    h.minimize = j["minimize"].get<bool>();
  }
  h.search = StudyFilesString(j, where, "search", false);
  h.parameters = StudyFilesStrings(j, where, "parameters");
  h.recordings = StudyFilesStrings(j, where, "recordings");
  h.recording_names = StudyFilesStrings(j, where, "recording_names");
  h.em_logs = StudyFilesStrings(j, where, "em_logs");
  h.created_utc = StudyFilesString(j, where, "created_utc", false);
  if (!h.recording_names.empty() && h.recording_names.size() != h.recordings.size()) {
    throw std::invalid_argument(where + ": 'recording_names' has " +
                                std::to_string(h.recording_names.size()) + " entries, " +
                                "'recordings' " + std::to_string(h.recordings.size()));
  }
  if (!h.em_logs.empty() && h.em_logs.size() != h.recordings.size()) {
    throw std::invalid_argument(where + ": 'em_logs' has " + std::to_string(h.em_logs.size()) +
                                " entries, 'recordings' " + std::to_string(h.recordings.size()));
  }
  return h;
}

void WriteTrialRequest(const fs::path& study, const StudyTrial& t) {
  StudyFilesCheckId(t.id, "WriteTrialRequest");
  if (t.id != TrialId(t.set_index, t.recording_index)) {
    throw std::invalid_argument("WriteTrialRequest: id '" + t.id + "' is not set " +
                                std::to_string(t.set_index) + ", recording " +
                                std::to_string(t.recording_index) + " ('" +
                                TrialId(t.set_index, t.recording_index) + "')");
  }
  StudyFilesWrite(TrialDir(study, t.id) / "request.json", RequestToJson(t.request));
}

void WriteTrialResult(const fs::path& study, const std::string& id, const TrialResult& r) {
  StudyFilesCheckId(id, "WriteTrialResult");
  StudyFilesWrite(TrialDir(study, id) / "result.json", ResultToJson(r));
}

std::string TaskOutcomeToJson(const TaskOutcome& o) {
  const Json j = {{"id", o.id},
                  {"exit_code", o.exit_code},
                  {"signal", o.signal},
                  {"timed_out", o.timed_out},
                  {"wall_s", std::isfinite(o.wall_s) ? Json(o.wall_s) : Json(nullptr)},
                  {"error", o.error}};
  return j.dump(2);
}

TaskOutcome TaskOutcomeFromJson(std::string_view json, std::string_view where) {
  const Json j = StudyFilesParseObject(json, where);
  TaskOutcome o;
  o.id = StudyFilesString(j, where, "id", true);
  o.exit_code = StudyFilesInt(j, where, "exit_code", true, -1);
  o.signal = StudyFilesInt(j, where, "signal", false, 0);
  if (j.contains("timed_out")) {
    if (!j["timed_out"].is_boolean())
      throw std::invalid_argument(StudyFilesField(where, "timed_out") + " must be true or false");
    o.timed_out = j["timed_out"].get<bool>();
  }
  if (j.contains("wall_s")) {
    if (j["wall_s"].is_null()) {
      o.wall_s = std::numeric_limits<double>::quiet_NaN();
    } else if (j["wall_s"].is_number()) {
      o.wall_s = j["wall_s"].get<double>();
    } else {
      throw std::invalid_argument(StudyFilesField(where, "wall_s") + " must be a number or null");
    }
  }
  o.error = StudyFilesString(j, where, "error", false);
  return o;
}

void WriteTaskOutcome(const fs::path& study, const TaskOutcome& o) {
  StudyFilesCheckId(o.id, "WriteTaskOutcome");
  StudyFilesWrite(TrialDir(study, o.id) / "outcome.json", TaskOutcomeToJson(o));
}

std::vector<StudyTrial> ReadTrials(const fs::path& study, std::vector<std::string>* problems) {
  auto problem = [&](std::string text) {
    if (problems != nullptr) problems->push_back(std::move(text));
  };
  std::vector<StudyTrial> trials;
  const fs::path root = study / "trials";
  std::error_code ec;
  if (!fs::is_directory(root, ec)) return trials;
  for (fs::directory_iterator it(root, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_directory(ec)) continue;
    const fs::path dir = it->path();
    const fs::path request_path = dir / "request.json";
    if (!fs::is_regular_file(request_path, ec)) continue;
    StudyTrial t;
    try {
      const std::string where = request_path.string();
      t.id = dir.filename().string();
      if (!StudyFilesParseId(t.id, &t.set_index, &t.recording_index))
        throw std::invalid_argument(where + ": its folder is not named s<set>-r<recording>");
      Json j = StudyFilesParseObject(StudyFilesRead(request_path), where);
      if (StudyFilesString(j, where, "id", false) != (j.contains("id") ? t.id : "") ||
          StudyFilesInt(j, where, "set_index", false, t.set_index) != t.set_index ||
          StudyFilesInt(j, where, "recording_index", false, t.recording_index) != t.recording_index)
        throw std::invalid_argument(where +
                                    ": id, set_index or recording_index disagree with "
                                    "the folder's name");
      j.erase("id");
      j.erase("set_index");
      j.erase("recording_index");
      t.request = RequestFromJson(j.dump(), where);
    } catch (const std::exception& e) {
      problem(std::string("trial left out: ") + e.what());
      continue;
    }
    const fs::path result_path = dir / "result.json";
    if (fs::exists(result_path, ec)) {
      try {
        t.result = ResultFromJson(StudyFilesRead(result_path), result_path.string());
      } catch (const std::exception& e) {
        problem(std::string("trial ") + t.id + " counted as unfinished: " + e.what());
      }
    }
    const fs::path outcome_path = dir / "outcome.json";
    if (fs::exists(outcome_path, ec)) {
      try {
        TaskOutcome o = TaskOutcomeFromJson(StudyFilesRead(outcome_path), outcome_path.string());
        if (o.id != t.id) {
          throw std::invalid_argument(outcome_path.string() + ": id '" + o.id +
                                      "' is not the trial's ('" + t.id + "')");
        }
        t.outcome = std::move(o);
      } catch (const std::exception& e) {
        problem(std::string("trial ") + t.id + ": outcome ignored: " + e.what());
      }
    }
    trials.push_back(std::move(t));
  }
  if (ec) problem(root.string() + ": listing stopped early (" + ec.message() + ")");
  std::sort(trials.begin(), trials.end(), [](const StudyTrial& a, const StudyTrial& b) {
    return std::tie(a.set_index, a.recording_index, a.id) <
           std::tie(b.set_index, b.recording_index, b.id);
  });
  return trials;
}

}  // namespace echoservo::tune
