// `echoservo info FILE [--json]`: what a volume file (.mha/.mhd/.vti/.nrrd) or a PLUS
// sequence (.igs.mha/.igs.nrrd) holds — frame count, one frame's dims, spacing (mm), origin
// (mm), element type, compression, per-frame field names and, for sequences, the timestamp
// range (s). Errors (missing/corrupt file) exit non-zero with a message naming the file.
#include <CLI/CLI.hpp>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>

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

}  // namespace

void AddInfoCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "info", "Describe a volume file or PLUS sequence (.mha .mhd .vti .nrrd .igs.mha .igs.nrrd)");
  auto file = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  cmd->add_option("FILE", *file, "volume or sequence file")->required();
  cmd->add_flag("--json", *json, "print JSON instead of text");
  cmd->callback([file, json] {
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
