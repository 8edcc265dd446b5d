// `echoservo detect VOLUME|SEQUENCE [--json] [--track]`: the catheter axis, guidewire tip
// and target of every frame of a volume file or PLUS sequence (tracking/radon_detector.h),
// in mm in each volume's image (physical) frame. Output:
//   {"frames": [{"found", "axis_point": [x,y,z], "axis_direction", "tip", "target",
//                "confidence", "tubularity", "tracked", "time_ms"}]}
// (axis/tip/target are null when not found; target is null when no tissue lies ahead).
#include <CLI/CLI.hpp>
#include <chrono>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "apps/commands/imaging_commands.h"
#include "imaging/io/recording.h"
#include "tracking/radon_detector.h"

namespace echoservo::apps {

namespace {

nlohmann::json Vec3(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

}  // namespace

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
  cmd->callback([file, json, track, options] {
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
