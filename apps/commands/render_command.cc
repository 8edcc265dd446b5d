// `echoservo render`: pictures of a volume for people. By default a PNG panel of three
// orthogonal slices and three maximum-intensity projections (OpenCV, no display needed);
// with --3d an isosurface view through VTK, which needs an X server (xvfb-run -a).
#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/commands/imaging_commands.h"
#include "apps/output.h"
#include "imaging/io/recording.h"
#include "imaging/render/volume_render.h"

namespace echoservo::apps {
namespace {

struct RenderFlags {
  std::string volume;
  bool phantom = false;
  std::string out;
  bool three_d = false;
  bool volume_rendering = false;
  double iso = 128.0;
  std::string tip, target, axis, slice_at, title;
  std::optional<long long> frame;
  int width = 900, height = 700;
  bool no_truth = false;
};

Eigen::Vector3d ParsePoint(const std::string& text, const std::string& option) {
  const std::vector<double> v = ParseNumberList(text, option);
  if (v.size() != 3) {
    throw std::invalid_argument(option + ": expected X,Y,Z (3 numbers in mm), got '" + text + "'");
  }
  return {v[0], v[1], v[2]};
}

// The volume to draw (frame --frame of a recording: 0-based position in the stream) and
// the simulator's ground truth when the recording carries it.
imaging::SourceFrame LoadFrame(const RenderFlags& f) {
  const long long wanted = f.frame.value_or(0);
  if (wanted < 0) throw std::invalid_argument("--frame must be >= 0");
  if (f.phantom) {
    if (!f.volume.empty()) throw std::invalid_argument("give either VOLUME or --phantom, not both");
    if (wanted != 0) throw std::invalid_argument("--frame: the phantom has frame 0 only");
    return {imaging::MakeRenderPhantom(), std::nullopt};
  }
  if (f.volume.empty()) throw std::invalid_argument("VOLUME is required (or --phantom)");
  if (!std::filesystem::exists(f.volume)) {
    throw std::invalid_argument("VOLUME: no such file: " + f.volume);
  }
  const std::unique_ptr<imaging::VolumeSource> source = imaging::OpenRecording(f.volume);
  for (long long n = 0;; ++n) {
    std::optional<imaging::SourceFrame> frame = source->Next();
    if (!frame) {
      throw std::invalid_argument("--frame " + std::to_string(wanted) + ": " + f.volume +
                                  " has only " + std::to_string(n) + " frame(s)");
    }
    if (n == wanted) return std::move(*frame);
  }
}

void RunRender(const RenderFlags& f) {
  if (f.out.empty()) throw std::invalid_argument("--out is required");
  imaging::RenderOverlays o;
  if (!f.tip.empty()) o.tip_mm = ParsePoint(f.tip, "--tip");
  if (!f.target.empty()) o.target_mm = ParsePoint(f.target, "--target");
  if (!f.slice_at.empty()) o.slice_point_mm = ParsePoint(f.slice_at, "--slice-at");
  if (!f.axis.empty()) {
    const std::vector<double> v = ParseNumberList(f.axis, "--axis");
    if (v.size() != 6) {
      throw std::invalid_argument("--axis: expected PX,PY,PZ,DX,DY,DZ (6 numbers), got '" + f.axis +
                                  "'");
    }
    o.axis_point_mm = Eigen::Vector3d(v[0], v[1], v[2]);
    o.axis_direction = Eigen::Vector3d(v[3], v[4], v[5]);
    if (o.axis_direction->norm() < 1e-12) {
      throw std::invalid_argument("--axis: the direction DX,DY,DZ is zero");
    }
  }
  o.title = f.title.empty() ? (f.phantom ? std::string("phantom") : f.volume) : f.title;

  std::string why;
  // Check the display before reading anything: a missing X server is the common mistake.
  if (f.three_d && !imaging::XDisplayAvailable(&why)) {
    throw std::runtime_error("--3d needs an X server (" + why + "); run under xvfb-run -a");
  }
  const imaging::SourceFrame frame = LoadFrame(f);
  const imaging::Volume& volume = frame.volume;
  if (frame.truth && !f.no_truth) o.truth = frame.truth;
  if (f.three_d) {
    imaging::IsosurfaceOptions options;
    options.width = f.width;
    options.height = f.height;
    options.volume_rendering = f.volume_rendering;
    imaging::RenderIsosurfacePng(volume, f.iso, o, f.out, options);
  } else {
    imaging::RenderSlicesPng(volume, o, f.out);
  }
  std::cout << "wrote " << f.out << "\n";
}

}  // namespace

void AddRenderCommand(CLI::App& app) {
  auto flags = std::make_shared<RenderFlags>();
  CLI::App* cmd = app.add_subcommand(
      "render",
      "Draw a volume as a PNG: three orthogonal slices and three maximum-intensity projections "
      "(default), or a 3D isosurface (--3d, needs an X server: run under xvfb-run -a). "
      "Overlay points are in the volume's image frame, mm.");
  cmd->add_option("VOLUME", flags->volume,
                  "volume file (.mha/.mhd/.vti/.nrrd), PLUS sequence (.igs.mha) or folder of "
                  "volumes");
  cmd->add_flag("--phantom", flags->phantom,
                "draw the built-in synthetic phantom (a bright line and a sphere) instead");
  cmd->add_option("--out,-o", flags->out, "PNG to write")->required();
  cmd->add_flag("--3d", flags->three_d, "isosurface view with VTK (needs an X server)");
  cmd->add_option("--iso", flags->iso, "isosurface level for --3d, voxel value 0-255")
      ->capture_default_str();
  cmd->add_flag("--volume-rendering", flags->volume_rendering,
                "with --3d: add a translucent ray-cast volume rendering");
  cmd->add_option("--tip", flags->tip, "detected tip X,Y,Z (mm)");
  cmd->add_option("--target", flags->target, "detected target X,Y,Z (mm)");
  cmd->add_option("--axis", flags->axis, "detected axis PX,PY,PZ,DX,DY,DZ (point, direction; mm)");
  cmd->add_option("--slice-at", flags->slice_at,
                  "where the slices cross, X,Y,Z (mm); default the tip, else the centre");
  cmd->add_option("--frame", flags->frame, "frame of a recording (sequence) to draw");
  cmd->add_flag("--no-truth", flags->no_truth,
                "do not draw the recording's ground truth (drawn in cyan when present)");
  cmd->add_option("--title", flags->title, "caption (default: the file name)");
  cmd->add_option("--width", flags->width, "--3d image width, px")->capture_default_str();
  cmd->add_option("--height", flags->height, "--3d image height, px")->capture_default_str();
  cmd->callback([flags] { RunRender(*flags); });
}

}  // namespace echoservo::apps
