// `echoservo reconstruct SEQUENCE.igs.mha --out VOLUME.mha`: freehand 3D reconstruction of a
// tracked 2D ultrasound sweep (imaging/reconstruct/freehand_reconstruction.h): the volume
// in the tracker (or --reference tool's) frame, frames used and skipped by reason, and with
// --compare-to the agreement with another volume in the same frame (docs/reconstruction.md).
#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/commands/imaging_commands.h"
#include "apps/output.h"
#include "imaging/io/plus_sequence.h"
#include "imaging/io/volume_io.h"
#include "imaging/reconstruct/freehand_reconstruction.h"

namespace echoservo::apps {
namespace {

namespace fs = std::filesystem;

struct ReconstructFlags {
  std::string sequence;
  std::string out;
  double spacing_mm = 0.5;
  std::string roi;
  std::string image_to_probe;
  std::string probe = "Probe";
  std::string reference;
  std::string method = "weighted";
  bool no_fill_holes = false;
  int fill_radius = 1;
  long long max_voxels = 512LL * 512 * 512;
  std::string compare_to;
  int compare_shift = 4;
  bool json = false;
};

// 16 numbers separated by spaces, commas, tabs or newlines; nullopt if `text` is not that.
std::optional<Eigen::Matrix4d> ParseSixteen(const std::string& text) {
  std::string t = text;
  for (char& c : t) {
    if (c == ',' || c == ';' || c == '\t' || c == '\n' || c == '\r') c = ' ';
  }
  std::istringstream in(t);
  std::vector<double> v;
  std::string token;
  while (in >> token) {
    std::size_t used = 0;
    double x = 0.0;
    try {
      x = std::stod(token, &used);
    } catch (const std::exception&) {
      return std::nullopt;
    }
    if (used != token.size()) return std::nullopt;
    v.push_back(x);
  }
  if (v.size() != 16) return std::nullopt;
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = v[4 * r + c];
  }
  return m;
}

Eigen::Matrix4d ParseImageToProbe(const std::string& text) {
  if (std::optional<Eigen::Matrix4d> m = ParseSixteen(text)) {
    imaging::ValidateImageToProbe(*m, "--image-to-probe");
    return *m;
  }
  if (!fs::is_regular_file(text)) {
    throw std::invalid_argument(
        "--image-to-probe: expected 16 numbers (row-major 4x4, mm per pixel included) or a file "
        "holding them, got '" +
        text + "'");
  }
  std::ifstream in(text);
  std::stringstream ss;
  ss << in.rdbuf();
  std::string body;
  for (std::string line; std::getline(ss, line);) {
    const std::size_t hash = line.find('#');
    body += (hash == std::string::npos ? line : line.substr(0, hash)) + "\n";
  }
  std::optional<Eigen::Matrix4d> m = ParseSixteen(body);
  if (!m) {
    throw std::invalid_argument("--image-to-probe: file " + text +
                                " does not hold exactly 16 numbers (row-major 4x4; '#' starts a "
                                "comment)");
  }
  imaging::ValidateImageToProbe(*m, "--image-to-probe (" + text + ")");
  return *m;
}

nlohmann::json Vec3(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

// The reconstruction's options from the flags, checked (std::invalid_argument naming the flag).
imaging::ReconstructionOptions ReconstructOptions(const ReconstructFlags& f) {
  if (f.sequence.empty()) throw std::invalid_argument("SEQUENCE is required");
  if (!fs::is_regular_file(f.sequence)) {
    throw std::invalid_argument("SEQUENCE: no such file: " + f.sequence);
  }
  if (f.out.empty()) throw std::invalid_argument("--out is required");
  {
    std::string ext = fs::path(f.out).extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".mha" && ext != ".mhd" && ext != ".vti") {
      throw std::invalid_argument("--out: " + f.out + ": extension must be .mha, .mhd or .vti");
    }
    const fs::path parent = fs::path(f.out).parent_path();
    if (!parent.empty() && !fs::is_directory(parent)) {
      throw std::invalid_argument("--out: folder " + parent.string() + " does not exist");
    }
  }
  imaging::ReconstructionOptions o;
  if (!std::isfinite(f.spacing_mm) || f.spacing_mm <= 0.0) {
    throw std::invalid_argument("--spacing must be a finite number of mm > 0");
  }
  o.spacing_mm = f.spacing_mm;
  if (!f.roi.empty()) {
    const std::vector<double> v = ParseNumberList(f.roi, "--roi");
    if (v.size() != 6) {
      throw std::invalid_argument(
          "--roi: expected XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (6 numbers, mm), got '" + f.roi + "'");
    }
    const Eigen::Vector3d lo(v[0], v[1], v[2]), hi(v[3], v[4], v[5]);
    if ((hi.array() <= lo.array()).any()) {
      throw std::invalid_argument("--roi: each max must exceed its min, got '" + f.roi + "'");
    }
    o.roi_mm = Eigen::AlignedBox3d(lo, hi);
  }
  if (!f.image_to_probe.empty()) o.image_to_probe = ParseImageToProbe(f.image_to_probe);
  if (f.probe.empty()) throw std::invalid_argument("--probe: empty tool name");
  o.probe_tool = f.probe;
  o.reference_tool = f.reference;
  if (f.method == "weighted") {
    o.compounding = imaging::Compounding::kWeighted;
  } else if (f.method == "nearest") {
    o.compounding = imaging::Compounding::kNearestLast;
  } else if (f.method == "nearest-mean") {
    o.compounding = imaging::Compounding::kNearestMean;
  } else {
    throw std::invalid_argument("--method: expected nearest, nearest-mean or weighted, got '" +
                                f.method + "'");
  }
  o.fill_holes = !f.no_fill_holes;
  if (f.fill_radius < 1 || f.fill_radius > 5) {
    throw std::invalid_argument("--fill-radius must be 1..5 voxels");
  }
  o.hole_fill_radius_voxels = f.fill_radius;
  if (f.max_voxels < 1) throw std::invalid_argument("--max-voxels must be >= 1");
  o.max_voxels = f.max_voxels;
  if (f.compare_shift < 0 || f.compare_shift > 50) {
    throw std::invalid_argument("--compare-shift must be 0..50 voxels");
  }
  if (!f.compare_to.empty() && !fs::is_regular_file(f.compare_to)) {
    throw std::invalid_argument("--compare-to: no such file: " + f.compare_to);
  }

  return o;
}

// The figures: JSON (--json) or lines.
void PrintReconstruction(const ReconstructFlags& f, const imaging::ReconstructionResult& r,
                         const std::optional<imaging::VolumeAgreement>& agreement) {
  const imaging::Volume& v = r.volume;
  if (f.json) {
    nlohmann::json j;
    j["sequence"] = f.sequence;
    j["out"] = f.out;
    j["frames_total"] = r.frames_total;
    j["frames_used"] = r.frames_used;
    j["frames_skipped"] = r.FramesSkipped();
    j["skipped"] = {{"image_status", r.skipped_image_status},
                    {"missing_transform", r.skipped_missing_transform},
                    {"invalid_status", r.skipped_invalid_status},
                    {"bad_transform", r.skipped_bad_transform}};
    j["output_frame"] = r.output_frame;
    j["calibration_source"] = r.calibration_source;
    nlohmann::json m = nlohmann::json::array();
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) m.push_back(r.image_to_probe(a, b));
    }
    j["image_to_probe"] = m;
    j["method"] = f.method;
    j["dims"] = {v.dims().x(), v.dims().y(), v.dims().z()};
    j["spacing_mm"] = f.spacing_mm;
    j["origin_mm"] = Vec3(v.origin_mm());
    j["voxels"] = v.voxel_count();
    j["voxels_known"] = r.voxels_known;
    j["voxels_filled_holes"] = r.voxels_filled_holes;
    j["pixels_outside"] = r.pixels_outside;
    if (agreement) {
      j["compare_to"] = f.compare_to;
      j["overlap_voxels"] = agreement->overlap_voxels;
      j["correlation"] = agreement->correlation;
      j["best_shift_mm"] = Vec3(agreement->best_shift_mm);
      j["best_correlation"] = agreement->best_correlation;
    }
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::cout << "frames: " << r.frames_used << " used, " << r.FramesSkipped() << " skipped of "
            << r.frames_total << " (ImageStatus not OK " << r.skipped_image_status
            << ", transform missing " << r.skipped_missing_transform << ", status not OK "
            << r.skipped_invalid_status << ", non-finite or not rigid " << r.skipped_bad_transform
            << ")\n"
            << "calibration: " << r.calibration_source << "\n"
            << "volume: " << v.dims().x() << " x " << v.dims().y() << " x " << v.dims().z()
            << " at " << f.spacing_mm << " mm, origin " << Fixed(v.origin_mm().x(), 3) << " "
            << Fixed(v.origin_mm().y(), 3) << " " << Fixed(v.origin_mm().z(), 3) << " mm ("
            << r.output_frame << " frame)\n"
            << "voxels: " << r.voxels_known << " from pixels, " << r.voxels_filled_holes
            << " hole-filled, of " << v.voxel_count() << "; " << r.pixels_outside
            << " pixels outside the region\n";
  if (agreement) {
    std::cout << "compare to " << f.compare_to << ": correlation "
              << Fixed(agreement->correlation, 3) << " over " << agreement->overlap_voxels
              << " voxels; best shift " << Fixed(agreement->best_shift_mm.x(), 2) << " "
              << Fixed(agreement->best_shift_mm.y(), 2) << " "
              << Fixed(agreement->best_shift_mm.z(), 2) << " mm (correlation "
              << Fixed(agreement->best_correlation, 3) << ")\n";
  }
  std::cout << "wrote " << f.out << "\n";
}

void RunReconstruct(const ReconstructFlags& f) {
  imaging::ReconstructionOptions o = ReconstructOptions(f);
  const imaging::PlusSequence sequence = imaging::ReadPlusSequence(f.sequence);
  const std::uint64_t pixels = sequence.FrameBytes() * sequence.frames.size();
  int last_decile = -1;
  if (pixels > 20'000'000) {
    o.progress = [&last_decile](std::size_t done, std::size_t total) {
      const int decile = static_cast<int>(10 * done / total);
      if (decile != last_decile) {
        last_decile = decile;
        std::cerr << "reconstruct: " << done << "/" << total << " frames\n";
      }
    };
  }
  const imaging::ReconstructionResult r = imaging::ReconstructFreehand(sequence, o);
  imaging::WriteVolume(r.volume, f.out);

  std::optional<imaging::VolumeAgreement> agreement;
  if (!f.compare_to.empty()) {
    agreement =
        imaging::CompareVolumes(r.volume, imaging::ReadVolume(f.compare_to), f.compare_shift);
  }

  PrintReconstruction(f, r, agreement);
}

}  // namespace

void AddReconstructCommand(CLI::App& app) {
  auto flags = std::make_shared<ReconstructFlags>();
  CLI::App* cmd = app.add_subcommand(
      "reconstruct",
      "Freehand 3D reconstruction of a tracked 2D ultrasound sweep (PLUS sequence): each pixel "
      "placed by ImageToProbe * ProbeToTracker (* TrackerToReference), compounded into a volume "
      "in the tracker (or reference) frame, holes filled (docs/reconstruction.md).");
  cmd->add_option("SEQUENCE", flags->sequence, "tracked 2D sequence (.igs.mha / .igs.nrrd)")
      ->required();
  cmd->add_option("--out,-o", flags->out, "volume to write (.mha, .mhd or .vti)")->required();
  cmd->add_option("--spacing", flags->spacing_mm, "output voxel pitch, mm")->capture_default_str();
  cmd->add_option("--roi", flags->roi,
                  "output region XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX in the output frame, mm (default: "
                  "the bounding box of the frames)");
  cmd->add_option("--image-to-probe", flags->image_to_probe,
                  "calibration: \"16 numbers\" (row-major 4x4, pixel -> probe mm, scale "
                  "included) or a file holding them; default the sequence's ImageToProbe field");
  cmd->add_option("--probe", flags->probe, "probe tool: frames' <PROBE>ToTrackerTransform")
      ->capture_default_str();
  cmd->add_option("--reference", flags->reference,
                  "reference tool: output in its frame, using <NAME>ToTrackerTransform");
  cmd->add_option("--method", flags->method,
                  "compounding: weighted (trilinear splat), nearest (last value) or nearest-mean")
      ->capture_default_str();
  cmd->add_flag("--no-fill-holes", flags->no_fill_holes, "leave empty voxels at 0");
  cmd->add_option("--fill-radius", flags->fill_radius, "hole-filling kernel radius, voxels (1-5)")
      ->capture_default_str();
  cmd->add_option("--max-voxels", flags->max_voxels, "refuse larger output volumes")
      ->capture_default_str();
  cmd->add_option("--compare-to", flags->compare_to,
                  "another volume in the same frame: correlation in the overlap and best shift");
  cmd->add_option("--compare-shift", flags->compare_shift,
                  "largest shift searched by --compare-to, voxels")
      ->capture_default_str();
  cmd->add_flag("--json", flags->json, "print JSON instead of text");
  cmd->callback([flags] { RunReconstruct(*flags); });
}

}  // namespace echoservo::apps
