// `echoservo info FILE|DIR [--json]`: what a volume file (.mha/.mhd/.vti/.nrrd) or a PLUS
// sequence (.igs.mha/.igs.nrrd) holds — frame count, one frame's dims, spacing (mm), origin
// (mm), element type, compression, per-frame field names and, for sequences, the timestamp
// range (s). Errors (missing/corrupt file) exit non-zero with a message naming the file.
// A folder: one line per volume, sequence and RUN directory in it (not recursive; other
// files are counted as ignored); a file that cannot be read is reported on its line and
// the others still listed, and the command then exits non-zero.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/commands/imaging_commands.h"
#include "imaging/io/plus_sequence.h"
#include "imaging/io/recording.h"
#include "imaging/io/sequence_reader.h"
#include "imaging/io/volume_io.h"

namespace echoservo::apps {

namespace {

nlohmann::json Vec3(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

nlohmann::json Describe(const std::filesystem::path& path) {
  nlohmann::json j;
  j["file"] = path.string();
  if (imaging::IsPlusSequenceFile(path)) {
    const imaging::SequenceReader reader(
        path);  // header and fields; uncompressed pixels stay on disk
    const imaging::PlusSequence& s = reader.sequence();
    j["kind"] = "sequence";
    j["frames"] = s.frames.size();
    j["dims"] = {s.frame_dims[0], s.frame_dims[1], s.frame_dims[2]};
    j["spacing"] = Vec3(s.spacing_mm);
    j["origin"] = Vec3(s.origin_mm);
    j["element_type"] = s.element_type;
    j["compressed"] = s.compressed;
    j["frame_fields"] = s.FrameFieldNames();
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    std::size_t stamped = 0;
    for (const auto& f : s.frames) {
      if (auto t = f.Timestamp()) {
        lo = std::min(lo, *t);
        hi = std::max(hi, *t);
        ++stamped;
      }
    }
    if (stamped > 0) {
      j["timestamp_range"] = {lo, hi};
      if (stamped > 1 && hi > lo) j["rate_hz"] = static_cast<double>(stamped - 1) / (hi - lo);
    } else {
      j["timestamp_range"] = nullptr;
    }
    return j;
  }
  const auto info = imaging::InspectVolumeFile(path);
  const auto v = imaging::ReadVolume(path);
  j["kind"] = "volume";
  j["format"] = info.format;
  j["frames"] = 1;
  j["dims"] = {v.dims().x(), v.dims().y(), v.dims().z()};
  j["spacing"] = Vec3(v.spacing_mm());
  j["origin"] = Vec3(v.origin_mm());
  j["element_type"] = info.element_type;
  j["compressed"] = info.compressed;
  j["frame_fields"] = nlohmann::json::array();
  return j;
}

std::string Join(const nlohmann::json& array, const std::string& sep = " ") {
  std::ostringstream out;
  bool first = true;
  for (const auto& x : array) {
    if (!first) out << sep;
    first = false;
    if (x.is_string()) {
      out << x.get<std::string>();
    } else {
      out << x.dump();
    }
  }
  return out.str();
}

namespace fs = std::filesystem;

// The files a RUN directory may hold (formats/run_record.h, live/demo_run.h).
constexpr const char* kRunFiles[] = {"run.json", "targets.csv", "servo.csv",   "latency.csv",
                                     "em.csv",   "truth.csv",   "report.html", "volumes.igs.mhd"};

// A RUN directory: which of its files are there, and its recorded volumes' frame count.
nlohmann::json DescribeRun(const fs::path& dir) {
  nlohmann::json j;
  j["file"] = dir.string();
  j["kind"] = "run";
  nlohmann::json files = nlohmann::json::array();
  for (const char* name : kRunFiles) {
    std::error_code ec;
    if (fs::exists(dir / name, ec)) files.push_back(name);
  }
  j["files"] = files;
  if (fs::exists(dir / "volumes.igs.mhd")) {
    const nlohmann::json v = Describe(dir / "volumes.igs.mhd");
    j["frames"] = v["frames"];
    j["dims"] = v["dims"];
  }
  return j;
}

bool IsRunDirectory(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir, ec) && fs::exists(dir / "run.json", ec);
}

// Every volume, sequence and RUN directory in `dir` (name order), each described or with
// the error that stopped it; `ignored` counts the other entries.
nlohmann::json DescribeFolder(const fs::path& dir) {
  std::vector<fs::path> paths;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    paths.push_back(it->path());
  if (ec) throw std::invalid_argument(dir.string() + ": cannot list the folder: " + ec.message());
  std::sort(paths.begin(), paths.end());
  nlohmann::json entries = nlohmann::json::array();
  std::size_t ignored = 0, errors = 0;
  for (const fs::path& p : paths) {
    const bool run = IsRunDirectory(p);
    if (!run && (fs::is_directory(p, ec) ||
                 !(imaging::IsPlusSequenceFile(p) || imaging::IsVolumeFile(p)))) {
      ++ignored;  // detached pixel data (.raw), notes, other folders
      continue;
    }
    try {
      entries.push_back(run ? DescribeRun(p) : Describe(p));
    } catch (const std::exception& e) {
      entries.push_back({{"file", p.string()}, {"kind", "error"}, {"error", e.what()}});
      ++errors;
    }
  }
  return {{"folder", dir.string()},
          {"kind", "folder"},
          {"entries", entries},
          {"errors", errors},
          {"ignored", ignored}};
}

// One line per entry of a folder.
void PrintFolder(const nlohmann::json& j) {
  std::cout << "folder " << j["folder"].get<std::string>() << ": " << j["entries"].size()
            << " entries (" << j["errors"].dump() << " unreadable, " << j["ignored"].dump()
            << " ignored: not a volume, sequence or RUN)\n";
  for (const auto& e : j["entries"]) {
    const std::string name = fs::path(e["file"].get<std::string>()).filename().string();
    const std::string kind = e["kind"].get<std::string>();
    std::cout << name << "  " << kind;
    if (kind == "error") {
      std::cout << ": " << e["error"].get<std::string>() << "\n";
      continue;
    }
    if (kind == "run") {
      std::cout << "  files: " << Join(e["files"], ", ");
      if (e.contains("frames")) std::cout << "  volumes: " << e["frames"].dump() << " frames";
      std::cout << "\n";
      continue;
    }
    std::cout << "  " << e["frames"].dump() << " frame" << (e["frames"] == 1 ? "" : "s") << "  "
              << Join(e["dims"], "x") << "  spacing " << Join(e["spacing"]) << " mm  "
              << e["element_type"].get<std::string>()
              << (e["compressed"].get<bool>() ? " compressed" : "");
    if (e.contains("timestamp_range") && !e["timestamp_range"].is_null())
      std::cout << "  t " << Join(e["timestamp_range"], " to ") << " s";
    std::cout << "\n";
  }
}

}  // namespace

void AddInfoCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "info",
      "Describe a volume file or PLUS sequence (.mha .mhd .vti .nrrd .igs.mha .igs.nrrd), or "
      "every volume, sequence and RUN directory in a folder");
  auto file = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  cmd->add_option("FILE", *file, "volume or sequence file, or a folder of them")->required();
  cmd->add_flag("--json", *json, "print JSON instead of text");
  cmd->callback([file, json] {
    std::error_code ec;
    if (fs::is_directory(*file, ec)) {
      const nlohmann::json j = DescribeFolder(*file);
      if (*json) {
        std::cout << j.dump(2) << "\n";
      } else {
        PrintFolder(j);
      }
      if (j["errors"].get<std::size_t>() > 0) {
        throw std::runtime_error(*file + ": " + j["errors"].dump() + " of " +
                                 std::to_string(j["entries"].size()) +
                                 " entries could not be read (listed above)");
      }
      if (j["entries"].empty()) {
        throw std::invalid_argument(
            *file +
            ": no volume (.mha .mhd .vti .nrrd), PLUS sequence (.igs.mha .igs.mhd "
            ".igs.nrrd) or RUN directory (run.json) in this folder");
      }
      return;
    }
    const nlohmann::json j = Describe(*file);
    if (*json) {
      std::cout << j.dump(2) << "\n";
      return;
    }
    std::cout << "file:          " << j["file"].get<std::string>() << "\n"
              << "kind:          " << j["kind"].get<std::string>() << "\n"
              << "frames:        " << j["frames"].dump() << "\n"
              << "dims:          " << Join(j["dims"], " x ") << "\n"
              << "spacing (mm):  " << Join(j["spacing"]) << "\n"
              << "origin (mm):   " << Join(j["origin"]) << "\n"
              << "element type:  " << j["element_type"].get<std::string>() << "\n"
              << "compressed:    " << (j["compressed"].get<bool>() ? "yes" : "no") << "\n";
    if (j.contains("timestamp_range") && !j["timestamp_range"].is_null()) {
      std::cout << "timestamps (s): " << Join(j["timestamp_range"], " to ") << "\n";
    }
    if (j.contains("rate_hz")) std::cout << "rate (Hz):     " << j["rate_hz"].dump() << "\n";
    std::cout << "frame fields:  "
              << (j["frame_fields"].empty() ? "(none)" : Join(j["frame_fields"], ", ")) << "\n";
  });
}

}  // namespace echoservo::apps
