#include "tune/study_spec.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace echoservo::tune {
namespace {

using SpecJson = nlohmann::json;
namespace spec_fs = std::filesystem;

// Every error starts with the SPEC's path and the item: "spec.json: parameters.x: …".
[[noreturn]] void SpecFail(const std::string& path, const std::string& item,
                           const std::string& why) {
  throw std::invalid_argument(path + ": " + item + ": " + why);
}

std::string SpecJoin(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

// Refuses keys outside `allowed` (a typo must not be silently ignored).
void SpecCheckKeys(const SpecJson& j, const std::vector<std::string>& allowed,
                   const std::string& path, const std::string& item) {
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (std::find(allowed.begin(), allowed.end(), it.key()) == allowed.end()) {
      SpecFail(path, item.empty() ? it.key() : item + "." + it.key(),
               "unknown key (allowed: " + SpecJoin(allowed) + ")");
    }
  }
}

double SpecNumber(const SpecJson& v, const std::string& path, const std::string& item) {
  if (!v.is_number()) SpecFail(path, item, "must be a number, got " + v.dump());
  const double x = v.get<double>();
  if (!std::isfinite(x)) SpecFail(path, item, "must be finite");
  return x;
}

double SpecNumberIn(const SpecJson& j, const char* key, double fallback, double lo, double hi,
                    const std::string& path, const std::string& item, const char* unit) {
  if (!j.contains(key)) return fallback;
  const std::string where = item + "." + key;
  const double x = SpecNumber(j[key], path, where);
  if (x < lo || x > hi) {
    std::ostringstream s;
    s << x << " " << unit << " is outside [" << lo << ", " << hi << "] " << unit;
    SpecFail(path, where, s.str());
  }
  return x;
}

long long SpecInteger(const SpecJson& v, const std::string& path, const std::string& item,
                      long long lo, long long hi) {
  if (!v.is_number_integer() && !(v.is_number_float() && std::isfinite(v.get<double>()) &&
                                  std::floor(v.get<double>()) == v.get<double>())) {
    SpecFail(path, item, "must be an integer, got " + v.dump());
  }
  const double d = v.get<double>();
  if (d < static_cast<double>(lo) || d > static_cast<double>(hi)) {
    SpecFail(path, item,
             v.dump() + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return static_cast<long long>(d);
}

// A parameter's value checked against the registry, the error naming the SPEC item.
void SpecCheckValue(const live::ParameterInfo& p, double v, const std::string& path,
                    const std::string& item) {
  try {
    live::CheckValue(p, v);
  } catch (const std::invalid_argument& e) {
    SpecFail(path, item, e.what());
  }
}

const live::ParameterInfo& SpecRequireParameter(const std::string& name, const std::string& path,
                                                const std::string& item) {
  try {
    return live::RequireParameter(name);
  } catch (const std::invalid_argument& e) {
    SpecFail(path, item, e.what());
  }
}

bool SpecEndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool SpecIsSequenceFile(const spec_fs::path& p) {
  std::string name = p.filename().string();
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return SpecEndsWith(name, ".mha") || SpecEndsWith(name, ".mhd") || SpecEndsWith(name, ".nrrd");
}

bool SpecIsRunDir(const spec_fs::path& p) {
  std::error_code ec;
  return spec_fs::is_regular_file(p / "volumes.igs.mhd", ec);
}

// A recording's short name: the file name without its extensions ("a.igs.mha" → "a"), a
// RUN directory's folder name.
std::string SpecBaseName(const spec_fs::path& p) {
  std::string name = p.filename().string();
  if (name.empty()) name = p.parent_path().filename().string();
  for (const char* ext : {".igs.mha", ".igs.mhd", ".igs.nrrd", ".mha", ".mhd", ".nrrd"}) {
    if (SpecEndsWith(name, ext) && name.size() > std::string(ext).size()) {
      name.resize(name.size() - std::string(ext).size());
      break;
    }
  }
  return name;
}

// Short unique names: the base name; where two collide, "parent/base"; then "#k".
void SpecNameRecordings(std::vector<RecordingSpec>& recs) {
  std::map<std::string, int> count;
  for (const RecordingSpec& r : recs) ++count[SpecBaseName(r.path)];
  std::set<std::string> used;
  for (RecordingSpec& r : recs) {
    const spec_fs::path p(r.path);
    std::string name = SpecBaseName(p);
    if (count[name] > 1) name = p.parent_path().filename().string() + "/" + name;
    std::string unique = name;
    for (int k = 2; used.count(unique) != 0; ++k) unique = name + "#" + std::to_string(k);
    used.insert(unique);
    r.name = unique;
  }
}

spec_fs::path SpecResolve(const std::string& text, const spec_fs::path& base) {
  spec_fs::path p(text);
  if (p.is_relative()) p = base / p;
  return spec_fs::absolute(p).lexically_normal();
}

// One "recordings" item: a file, a RUN directory, or a folder of them (sorted).
std::vector<RecordingSpec> SpecExpandRecording(const SpecJson& item, const spec_fs::path& base,
                                               const std::string& path, const std::string& where) {
  std::string text, em;
  if (item.is_string()) {
    text = item.get<std::string>();
  } else if (item.is_object()) {
    SpecCheckKeys(item, {"path", "em"}, path, where);
    if (!item.contains("path") || !item["path"].is_string())
      SpecFail(path, where + ".path", "missing (a recording file or folder, a string)");
    text = item["path"].get<std::string>();
    if (item.contains("em")) {
      if (!item["em"].is_string()) SpecFail(path, where + ".em", "must be a path (a string)");
      em = SpecResolve(item["em"].get<std::string>(), base).string();
    }
  } else {
    SpecFail(path, where, "must be a path or {\"path\": …, \"em\": …}, got " + item.dump());
  }
  if (text.empty()) SpecFail(path, where, "empty path");
  const spec_fs::path p = SpecResolve(text, base);
  std::error_code ec;
  if (!spec_fs::exists(p, ec))
    SpecFail(path, where, "'" + text + "' (" + p.string() + ") does not exist");
  std::vector<spec_fs::path> found;
  if (spec_fs::is_directory(p, ec) && !SpecIsRunDir(p)) {
    if (!em.empty()) SpecFail(path, where + ".em", "an EM log needs one recording, not a folder");
    for (spec_fs::directory_iterator it(p, ec), end; !ec && it != end; it.increment(ec)) {
      const spec_fs::path q = it->path();
      if (it->is_directory(ec) ? SpecIsRunDir(q) : SpecIsSequenceFile(q)) found.push_back(q);
    }
    if (ec) SpecFail(path, where, p.string() + ": cannot be listed (" + ec.message() + ")");
    std::sort(found.begin(), found.end());
    if (found.empty()) {
      SpecFail(path, where,
               "folder " + p.string() +
                   " holds no recording (.mha, .mhd or .nrrd files, or RUN directories with "
                   "volumes.igs.mhd)");
    }
  } else {
    found.push_back(p);
  }
  std::vector<RecordingSpec> out;
  for (const spec_fs::path& q : found) {
    RecordingSpec r;
    r.path = q.string();
    r.em_log = em;
    try {
      r.info = InspectRecording(r.path, r.em_log);
    } catch (const std::exception& e) {
      SpecFail(path, where, std::string("recording ") + r.path + " cannot be used: " + e.what());
    }
    out.push_back(std::move(r));
  }
  return out;
}

std::vector<double> SpecLinspace(double lo, double hi, long long steps, bool integral) {
  std::vector<double> v;
  for (long long i = 0; i < steps; ++i) {
    double x =
        steps == 1 ? lo : lo + (hi - lo) * static_cast<double>(i) / static_cast<double>(steps - 1);
    if (i == steps - 1) x = hi;
    if (integral) x = std::round(x);
    if (v.empty() || v.back() != x) v.push_back(x);
  }
  return v;
}

ParameterAxis SpecParseAxis(const std::string& name, const SpecJson& j, const std::string& path) {
  const std::string item = "parameters." + name;
  const live::ParameterInfo& p = SpecRequireParameter(name, path, item);
  if (!j.is_object()) {
    SpecFail(
        path, item,
        "must be {\"values\": [...]} or {\"min\": a, \"max\": b[, \"steps\": n]}, got " + j.dump());
  }
  SpecCheckKeys(j, {"values", "min", "max", "steps"}, path, item);
  ParameterAxis a;
  a.name = name;
  const bool integral = p.kind != live::ParameterKind::kReal;
  if (j.contains("values")) {
    if (j.contains("min") || j.contains("max") || j.contains("steps"))
      SpecFail(path, item, "give either \"values\" or a range (\"min\", \"max\"), not both");
    if (!j["values"].is_array() || j["values"].empty())
      SpecFail(path, item + ".values", "must be a non-empty array of numbers");
    for (std::size_t i = 0; i < j["values"].size(); ++i) {
      const std::string where = item + ".values[" + std::to_string(i) + "]";
      const double v = SpecNumber(j["values"][i], path, where);
      SpecCheckValue(p, v, path, where);
      if (std::find(a.values.begin(), a.values.end(), v) != a.values.end())
        SpecFail(path, where, "value listed twice");
      a.values.push_back(v);
    }
    a.min = *std::min_element(a.values.begin(), a.values.end());
    a.max = *std::max_element(a.values.begin(), a.values.end());
    return a;
  }
  if (!j.contains("min") || !j.contains("max"))
    SpecFail(path, item, "needs \"values\", or \"min\" and \"max\"");
  a.min = SpecNumber(j["min"], path, item + ".min");
  a.max = SpecNumber(j["max"], path, item + ".max");
  SpecCheckValue(p, a.min, path, item + ".min");
  SpecCheckValue(p, a.max, path, item + ".max");
  if (!(a.min < a.max)) SpecFail(path, item, "min must be below max (a single value: \"fixed\")");
  if (j.contains("steps")) {
    const long long steps = SpecInteger(j["steps"], path, item + ".steps", 2, 100000);
    a.values = SpecLinspace(a.min, a.max, steps, integral);
  }
  return a;
}

}  // namespace

StudySpec ParseStudySpec(std::string_view json, const std::string& path) {
  const std::string where = path.empty() ? std::string("SPEC") : path;
  SpecJson j = SpecJson::parse(json.begin(), json.end(), nullptr, false);
  if (j.is_discarded()) {
    // Parse again for the position of the syntax error.
    try {
      // GCC does not take a (void) cast as using a [[nodiscard]]-like result.
      [[maybe_unused]] const SpecJson again = SpecJson::parse(json.begin(), json.end());
    } catch (const SpecJson::parse_error& e) {
      throw std::invalid_argument(where + ": not valid JSON (" + e.what() + ")");
    }
    throw std::invalid_argument(where + ": not valid JSON");
  }
  if (!j.is_object()) throw std::invalid_argument(where + ": not a JSON object");
  SpecCheckKeys(j,
                {"recordings", "scoring", "parameters", "fixed", "search", "timeout_s", "jobs",
                 "description"},
                where, "");
  const spec_fs::path base =
      path.empty() ? spec_fs::current_path() : spec_fs::absolute(spec_fs::path(path)).parent_path();
  StudySpec s;
  SpecJson norm = SpecJson::object();

  // scoring (first: the recordings are checked against the metric).
  if (!j.contains("scoring") || !j["scoring"].is_object())
    SpecFail(where, "scoring", "missing (an object with \"metric\")");
  const SpecJson& sc = j["scoring"];
  SpecCheckKeys(sc, {"metric", "goal", "latency_s", "delay_s", "from_s"}, where, "scoring");
  if (!sc.contains("metric") || !sc["metric"].is_string())
    SpecFail(where, "scoring.metric", "missing (a metric name, a string)");
  s.metric = sc["metric"].get<std::string>();
  std::vector<std::string> names;
  for (const MetricInfo& m : Metrics()) names.push_back(m.name);
  if (std::find(names.begin(), names.end(), s.metric) == names.end())
    SpecFail(where, "scoring.metric",
             "unknown metric '" + s.metric + "' (known: " + SpecJoin(names) + ")");
  s.minimize = s.metric != metric::kFoundFraction;
  if (sc.contains("goal")) {
    const SpecJson& g = sc["goal"];
    if (g == "minimize") {
      s.minimize = true;
    } else if (g == "maximize") {
      s.minimize = false;
    } else {
      SpecFail(where, "scoring.goal", "must be \"minimize\" or \"maximize\", got " + g.dump());
    }
  }
  s.latency_s = SpecNumberIn(sc, "latency_s", 0.1, 0.0, 1.0, where, "scoring", "s");
  s.delay_s = SpecNumberIn(sc, "delay_s", -1.0, 0.0, 1.0, where, "scoring", "s");
  s.from_s = SpecNumberIn(sc, "from_s", 3.0, 0.0, 60.0, where, "scoring", "s");
  s.loop = s.metric == metric::kLoopRms;

  // recordings
  if (!j.contains("recordings") || !j["recordings"].is_array() || j["recordings"].empty())
    SpecFail(where, "recordings", "missing (a non-empty array of files or folders)");
  for (std::size_t i = 0; i < j["recordings"].size(); ++i) {
    const std::string item = "recordings[" + std::to_string(i) + "]";
    for (RecordingSpec& r : SpecExpandRecording(j["recordings"][i], base, where, item)) {
      for (const RecordingSpec& other : s.recordings) {
        if (other.path == r.path) SpecFail(where, item, "recording " + r.path + " listed twice");
      }
      const std::string why = MetricUnavailableReason(r.info, s.metric);
      if (!why.empty()) {
        SpecFail(where, item, "metric " + s.metric + " cannot be scored on " + r.path + ": " + why);
      }
      s.recordings.push_back(std::move(r));
    }
  }
  SpecNameRecordings(s.recordings);

  // parameters
  if (j.contains("parameters")) {
    if (!j["parameters"].is_object())
      SpecFail(where, "parameters", "must be an object {name: {values | min, max[, steps]}}");
    for (auto it = j["parameters"].begin(); it != j["parameters"].end(); ++it)
      s.axes.push_back(SpecParseAxis(it.key(), it.value(), where));
  }

  // fixed
  if (j.contains("fixed")) {
    if (!j["fixed"].is_object()) SpecFail(where, "fixed", "must be an object {name: value}");
    for (auto it = j["fixed"].begin(); it != j["fixed"].end(); ++it) {
      const std::string item = "fixed." + it.key();
      const live::ParameterInfo& p = SpecRequireParameter(it.key(), where, item);
      const double v = SpecNumber(it.value(), where, item);
      SpecCheckValue(p, v, where, item);
      for (const ParameterAxis& a : s.axes) {
        if (a.name == it.key())
          SpecFail(where, item, "also listed in \"parameters\": fix it or search it, not both");
      }
      s.fixed.emplace_back(it.key(), v);
    }
    live::PipelineSettings settings = live::DefaultSettings();
    try {
      live::Apply(s.fixed, settings);
    } catch (const std::invalid_argument& e) {
      SpecFail(where, "fixed", e.what());
    }
  }

  // search
  if (j.contains("search")) {
    const SpecJson& se = j["search"];
    if (!se.is_object()) SpecFail(where, "search", "must be an object {\"method\": …}");
    SpecCheckKeys(se, {"method", "trials", "seed"}, where, "search");
    if (se.contains("method")) {
      if (!se["method"].is_string())
        SpecFail(where, "search.method", "must be \"grid\", \"random\" or \"adaptive\"");
      s.method = se["method"].get<std::string>();
    }
    if (s.method != "grid" && s.method != "random" && s.method != "adaptive") {
      SpecFail(where, "search.method",
               "unknown search method '" + s.method + "' (grid, random, adaptive)");
    }
    if (se.contains("trials")) {
      if (s.method == "grid")
        SpecFail(where, "search.trials", "a grid tries every combination: no \"trials\"");
      s.trials = static_cast<int>(SpecInteger(se["trials"], where, "search.trials", 1, 100000));
    }
    if (se.contains("seed")) {
      s.seed = static_cast<std::uint64_t>(SpecInteger(se["seed"], where, "search.seed", 0,
                                                      std::numeric_limits<std::int64_t>::max()));
    }
  }
  if (s.method != "grid") {
    if (s.axes.empty())
      SpecFail(where, "parameters", "a " + s.method + " search needs at least one parameter");
    if (s.trials == 0)
      SpecFail(where, "search.trials", "missing: how many parameter sets to try (>= 1)");
  }
  for (const ParameterAxis& a : s.axes) {
    const live::ParameterInfo& p = live::RequireParameter(a.name);
    const std::string item = "parameters." + a.name;
    if (s.method == "grid" && a.values.empty())
      SpecFail(where, item, "a grid needs \"values\" or \"steps\"");
    if (s.method == "adaptive") {
      if (p.kind != live::ParameterKind::kReal) {
        SpecFail(where, item,
                 "an integer or boolean parameter cannot be searched adaptively (BOBYQA is "
                 "continuous): use \"grid\" or \"random\", or fix it in \"fixed\"");
      }
      if (!a.values.empty())
        SpecFail(where, item,
                 "an adaptive search takes a range {\"min\", \"max\"}, without "
                 "\"values\" or \"steps\"");
    }
  }

  // execution (not part of what the study computes: a rerun may change them)
  s.timeout_s = SpecNumberIn(j, "timeout_s", 600.0, 1e-3, 86400.0, where, "", "s");
  if (j.contains("jobs")) s.jobs = static_cast<int>(SpecInteger(j["jobs"], where, "jobs", 0, 4096));
  if (j.contains("description") && !j["description"].is_string())
    SpecFail(where, "description", "must be a string");

  // The normalised SPEC: what the study's results depend on (study.json; a rerun with a
  // different one is refused). Execution settings (jobs, timeout_s) and the description
  // are left out.
  SpecJson recs = SpecJson::array();
  for (const RecordingSpec& r : s.recordings)
    recs.push_back({{"path", r.path}, {"em", r.em_log}, {"name", r.name}});
  norm["recordings"] = recs;
  norm["scoring"] = {{"metric", s.metric},
                     {"goal", s.minimize ? "minimize" : "maximize"},
                     {"latency_s", s.latency_s},
                     {"delay_s", s.delay_s},
                     {"from_s", s.from_s}};
  SpecJson params = SpecJson::object();
  for (const ParameterAxis& a : s.axes) {
    SpecJson ax = {{"min", a.min}, {"max", a.max}};
    if (!a.values.empty()) ax["values"] = a.values;
    params[a.name] = ax;
  }
  norm["parameters"] = params;
  SpecJson fixed = SpecJson::object();
  for (const live::Assignment& f : s.fixed) fixed[f.first] = f.second;
  norm["fixed"] = fixed;
  norm["search"] = {{"method", s.method}, {"trials", s.trials}, {"seed", s.seed}};
  s.normalised_json = norm.dump(2);
  s.path = path.empty() ? std::string() : spec_fs::absolute(spec_fs::path(path)).string();
  return s;
}

StudySpec ReadStudySpec(const std::string& path) {
  std::error_code ec;
  if (!spec_fs::is_regular_file(path, ec))
    throw std::invalid_argument(path + ": SPEC file not found (a JSON file, docs/tuning.md)");
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in && !in.eof()) throw std::invalid_argument(path + ": SPEC cannot be read");
  return ParseStudySpec(text.str(), path);
}

}  // namespace echoservo::tune
