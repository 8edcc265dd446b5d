// `echoservo detect VOLUME|SEQUENCE [--json] [--track] [--probe-apex X,Y,Z | --beam-direction
// X,Y,Z]`: the catheter axis, guidewire tip and target of every frame of a volume file or PLUS
// sequence (tracking/radon_detector.h), in mm in each volume's image (physical) frame. The
// beams come from the file's image-to-probe transform, or from --probe-apex (image mm) or
// --beam-direction (a linear probe's parallel beams, image frame); neither: unknown beams
// (the symmetric centre-line fit). Output:
//   {"frames": [{"found", "axis_point": [x,y,z], "axis_direction", "tip", "target",
//                "confidence", "tubularity", "tracked", "time_ms"}]}
// (axis/tip/target are null when not found; target is null when no tissue lies ahead).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "apps/commands/imaging_commands.h"
#include "apps/commands/set_flags.h"
#include "imaging/io/recording.h"
#include "live/pipeline_parameters.h"
#include "tracking/radon_detector.h"

namespace echoservo::apps {

namespace {

// "X,Y,Z" → a finite vector in *out (non-zero when `non_zero`); empty when valid, else why not.
std::string Vec3Problem(const std::string& text, bool non_zero, Eigen::Vector3d* out) {
  Eigen::Vector3d v;
  std::size_t pos = 0;
  for (int a = 0; a < 3; ++a) {
    const std::size_t end = text.find(',', pos);
    if ((a < 2) != (end != std::string::npos))
      return "expected X,Y,Z (three comma-separated numbers), got '" + text + "'";
    const std::string part = text.substr(pos, a < 2 ? end - pos : std::string::npos);
    std::size_t used = 0;
    double x = 0;
    try {
      x = std::stod(part, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != part.size() || !std::isfinite(x))
      return "'" + part + "' is not a finite number (in '" + text + "')";
    v[a] = x;
    pos = end + 1;
  }
  if (non_zero && !(v.norm() > 1e-9)) return "the direction must be non-zero";
  if (out) *out = v;
  return {};
}

// The option's vector; std::invalid_argument naming the option when it is not valid.
Eigen::Vector3d ParseVec3(const std::string& text, const std::string& option, bool non_zero) {
  Eigen::Vector3d v;
  if (const std::string why = Vec3Problem(text, non_zero, &v); !why.empty())
    throw std::invalid_argument(option + ": " + why);
  return v;
}

nlohmann::json Vec3(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

}  // namespace

tracking::RadonDetectorOptions WithDetectSet(const tracking::RadonDetectorOptions& options,
                                             const std::vector<live::Assignment>& assignments) {
  live::PipelineSettings settings = live::DefaultSettings();
  settings.tracker.detector = options;
  try {
    live::Apply(live::RequireStages(assignments, "detect", {"detector", "target"}), settings);
  } catch (const std::invalid_argument& e) {
    const std::string why = e.what();
    throw std::invalid_argument(why.rfind("--set", 0) == 0 ? why : "detect --set: " + why);
  }
  return settings.tracker.detector;
}

void AddDetectCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "detect", "Detect the catheter axis, tip and target in a volume or PLUS sequence");
  auto file = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  auto track = std::make_shared<bool>(false);
  cmd->add_option("FILE", *file, "volume or sequence file")->required();
  cmd->add_flag("--json", *json, "print JSON instead of text");
  cmd->add_flag("--track", *track, "search near the previous frame's axis (full search when lost)");
  auto options = std::make_shared<tracking::RadonDetectorOptions>();
  cmd->add_option("--sheath-diameter", options->fit.sheath_diameter_mm,
                  "outer diameter of the catheter sheath, mm (0: the echoes are the axis)")
      ->check(CLI::Range(0.0, 20.0))
      ->capture_default_str();
  cmd->add_option("--wire-diameter", options->fit.wire_diameter_mm,
                  "outer diameter of the guidewire, mm (at most the sheath's)")
      ->check(CLI::Range(0.0, 20.0))
      ->capture_default_str();
  cmd->add_option("--dynamic-range", options->edge.dynamic_range_db,
                  "the scanner's display dynamic range, dB (0-255 spans it)")
      ->check(CLI::Range(1.0, 120.0))
      ->capture_default_str();
  cmd->add_option("--min-confidence", options->min_confidence, "below: not found")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  auto apex = std::make_shared<std::string>();
  auto beam_direction = std::make_shared<std::string>();
  auto* apex_opt =
      cmd->add_option("--probe-apex", *apex,
                      "the probe apex X,Y,Z (image frame, mm): beams run from it (for a file "
                      "without an image-to-probe transform)")
          ->check([](const std::string& t) { return Vec3Problem(t, false, nullptr); });
  cmd->add_option("--beam-direction", *beam_direction,
                  "a linear probe's beam direction X,Y,Z (image frame, away from the probe; "
                  "non-zero): parallel beams")
      ->check([](const std::string& t) { return Vec3Problem(t, true, nullptr); })
      ->excludes(apex_opt);
  auto set = std::make_shared<SetFlags>();
  AddSetFlags(*cmd, *set);
  cmd->callback([file, json, track, options, apex, beam_direction, set] {
    if (!apex->empty())
      options->beams = tracking::BeamGeometry::FromApex(ParseVec3(*apex, "--probe-apex", false));
    if (!beam_direction->empty())
      options->beams =
          tracking::BeamGeometry::Parallel(ParseVec3(*beam_direction, "--beam-direction", true));
    // --set: the detector's and the target profile's parameters, over the flags above.
    if (!set->assignments.empty())
      *options = WithDetectSet(*options, set->ParsedFor("detect", {"detector", "target"}));
    tracking::RadonDetector detector(*options);  // validates the combination (wire ≤ sheath)
    auto source = imaging::OpenRecording(*file);
    nlohmann::json frames = nlohmann::json::array();
    while (auto frame = source->Next()) {
      const auto t0 = std::chrono::steady_clock::now();
      tracking::CatheterDetection d;
      bool error = false;
      std::string message;
      try {
        d = *track ? detector.Track(frame->volume) : detector.Detect(frame->volume);
      } catch (const std::invalid_argument& e) {
        error = true;
        message = e.what();
      }
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      nlohmann::json j;
      j["found"] = d.found;
      j["axis_point"] = d.found ? Vec3(d.axis.point) : nlohmann::json(nullptr);
      j["axis_direction"] = d.found ? Vec3(d.axis.direction) : nlohmann::json(nullptr);
      j["tip"] = d.found ? Vec3(d.tip_mm) : nlohmann::json(nullptr);
      j["target"] = d.found && d.target_found ? Vec3(d.target_mm) : nlohmann::json(nullptr);
      j["contact"] = d.found && d.target_found && d.contact;
      j["target_gap_mm"] =
          d.found && d.target_found ? nlohmann::json(d.target_gap_mm) : nlohmann::json(nullptr);
      j["confidence"] = d.confidence;
      j["tubularity"] = d.tubularity;
      j["tracked"] = d.tracked;
      j["time_ms"] = ms;
      if (error) j["error"] = message;
      frames.push_back(j);
    }
    nlohmann::json out;
    out["frames"] = frames;
    if (*json) {
      std::cout << out.dump(2) << "\n";
      return;
    }
    int i = 0;
    for (const auto& f : frames) {
      std::cout << "frame " << i++ << ": ";
      if (f.contains("error")) {
        std::cout << "error: " << f["error"].get<std::string>() << "\n";
      } else if (!f["found"].get<bool>()) {
        std::cout << "not found (confidence " << f["confidence"].dump() << ")\n";
      } else {
        std::cout << "axis " << f["axis_point"].dump() << " dir " << f["axis_direction"].dump()
                  << " tip " << f["tip"].dump() << " target " << f["target"].dump()
                  << " confidence " << f["confidence"].dump() << " (" << f["time_ms"].dump()
                  << " ms)\n";
      }
    }
  });
}

}  // namespace echoservo::apps
