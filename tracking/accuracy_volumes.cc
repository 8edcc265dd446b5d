#include "tracking/accuracy_volumes.h"

#include <Eigen/Geometry>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <random>
#include <stdexcept>

#include "imaging/io/volume_io.h"
#include "imaging/sim/catheter_scene.h"
#include "imaging/sim/simulated_scanner.h"
#include "tracking/independent_volumes.h"

namespace echoservo::tracking {
namespace {

using imaging::sim::AcousticProperties;
using imaging::sim::SimulatedScannerOptions;

constexpr double kTipFromBaseMm = 48.0;  // sheath 40 + wire protrusion 8 (default geometry)

struct Pose {
  double yaw_deg = 0, tilt_deg = 10, depth_mm = 60, lateral_mm = 0, advance_mm = 0;
};

// Moderate poses around the default scene (the water tank's catheter entering from ±x).
Pose ModeratePose(std::mt19937_64& rng, int index) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Pose p;
  p.yaw_deg = -30 + 60 * u(rng) + (index % 2 ? 180.0 : 0.0);
  p.tilt_deg = 15 * u(rng);
  p.depth_mm = 50 + 20 * u(rng);
  p.lateral_mm = -5 + 10 * u(rng);
  p.advance_mm = 4 * u(rng);
  return p;
}

Pose WidePose(std::mt19937_64& rng, int index) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Pose p;
  p.yaw_deg = -60 + 120 * u(rng) + (index % 2 ? 180.0 : 0.0);
  p.tilt_deg = -5 + 30 * u(rng);
  p.depth_mm = 40 + 40 * u(rng);
  p.lateral_mm = -10 + 20 * u(rng);
  p.advance_mm = 6 * u(rng);
  return p;
}

void SetPose(const Pose& p, SimulatedScannerOptions& o) {
  imaging::sim::PlaceCatheterScene({p.yaw_deg, p.tilt_deg, p.depth_mm, p.lateral_mm, p.advance_mm},
                                   o);
}

Eigen::Isometry3d BaseToWorld(const Pose& p) {
  SimulatedScannerOptions o;
  SetPose(p, o);
  return o.catheter_pose.base_to_world;
}

// A point on the (tip at advance 0) catheter axis, s mm from the tip, world frame.
Eigen::Vector3d AxisPoint(const Pose& p, double s_mm) {
  const Eigen::Isometry3d base = BaseToWorld(p);
  return base * Eigen::Vector3d(0, 0, kTipFromBaseMm + s_mm);
}

// Bright tissue blobs (cubes, 3–6 mm) 7–10 mm beside the catheter axis: near it, never on it
// (a cube's half-diagonal is ≤ 5.2 mm, the sheath's radius 1.25 mm).
void AddClutter(const Pose& p, std::mt19937_64& rng, SimulatedScannerOptions& o) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  AcousticProperties bright;
  bright.specular = 0.8;
  bright.specularity = 2.0;
  bright.diffuse = 0.15;
  bright.transmission = 0.8;
  bright.scatter = 0.1;
  const Eigen::Isometry3d base = BaseToWorld(p);
  const Eigen::Vector3d ex = base.linear().col(0), ey = base.linear().col(1);
  for (int i = 0; i < 4; ++i) {
    const double s = -38 + 42 * u(rng), phi = 2 * std::numbers::pi * u(rng), off = 7 + 3 * u(rng);
    const double h = 1.5 + 1.5 * u(rng);
    SimulatedScannerOptions::ExtraMesh m;
    m.mesh = imaging::sim::MakeBox(Eigen::Vector3d::Constant(-h), Eigen::Vector3d::Constant(h));
    m.properties = bright;
    m.mesh_to_world = Eigen::Isometry3d::Identity();
    m.mesh_to_world.translation() =
        AxisPoint(p, s) + off * (std::cos(phi) * ex + std::sin(phi) * ey);
    o.extra_meshes.push_back(std::move(m));
  }
}

// A weakly transmitting plate (18 × 12 × 1.5 mm) 15 mm above (towards the probe) the sheath
// 28 mm proximal of the tip: it shadows part of the sheath, not the tip.
void AddShadowPlate(const Pose& p, SimulatedScannerOptions& o) {
  AcousticProperties plate;
  plate.specular = 0.3;
  plate.specularity = 6.0;
  plate.diffuse = 0.05;
  plate.transmission = 0.1;
  const Eigen::Vector3d dir = BaseToWorld(p).linear().col(2);
  Eigen::Vector3d h(dir.x(), dir.y(), 0.0);
  h = h.norm() > 1e-6 ? h.normalized() : Eigen::Vector3d::UnitX();
  SimulatedScannerOptions::ExtraMesh m;
  m.mesh = imaging::sim::MakeBox(Eigen::Vector3d(-9, -6, -0.75), Eigen::Vector3d(9, 6, 0.75));
  m.properties = plate;
  m.mesh_to_world = Eigen::Isometry3d::Identity();
  m.mesh_to_world.linear().col(0) = h;
  m.mesh_to_world.linear().col(1) = Eigen::Vector3d::UnitZ().cross(h);
  m.mesh_to_world.linear().col(2) = Eigen::Vector3d::UnitZ();
  m.mesh_to_world.translation() = AxisPoint(p, -28.0) - Eigen::Vector3d(0, 0, 15.0);
  o.extra_meshes.push_back(std::move(m));
}

// FNV-1a of the class name mixed with the seed and index (splitmix64 finaliser): the same
// volume on every platform and run.
std::uint64_t MixSeed(std::uint64_t seed, const std::string& name, int index) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : name) h = (h ^ c) * 1099511628211ull;
  std::uint64_t z = h ^ (seed * 0x9E3779B97F4A7C15ull) ^ (static_cast<std::uint64_t>(index) << 32);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

std::string Label(const Pose& p, const SimulatedScannerOptions& o) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "yaw %.1f tilt %.1f depth %.1f lateral %.1f advance %.1f c %.0f",
                p.yaw_deg, p.tilt_deg, p.depth_mm, p.lateral_mm, p.advance_mm,
                o.medium_sound_speed_m_s);
  return buf;
}

SimulatedScannerOptions SceneOptions(const std::string& name, int index, std::mt19937_64& rng,
                                     Pose& pose) {
  SimulatedScannerOptions o;
  o.seed = rng() % 1000000 + 1;
  o.reverberation = true;
  pose = name == "wide_poses" ? WidePose(rng, index) : ModeratePose(rng, index);
  if (name == "no_reverberation") o.reverberation = false;
  if (name == "sound_speed")
    o.medium_sound_speed_m_s = (index % 3 == 0) ? 1540.0 : (index % 3 == 1) ? 1600.0 : 1482.0;
  if (name == "speckle_clutter" || name == "free_clutter") {
    o.background_scatter = 0.03;
    AddClutter(pose, rng, o);
  }
  if (name == "shadowing") AddShadowPlate(pose, o);
  if (name.rfind("free_", 0) == 0) o.catheter = false;
  if (name == "free_tank") o.annulus = false;
  SetPose(pose, o);
  return o;
}

// Independent-generator classes (tracking/independent_volumes.h): "beam_AA" (angle AA° to the
// beam, the volume knows its image-to-probe pose), "beam_AA_unknown" (it does not),
// "indep_free" (no catheter, unknown beams); "deep_AA" (AA° to the beam, the tip 80–100 mm
// from the apex, SetDeepObliquePhysics, known beams), "deep_free" (no catheter, unknown beams).
bool IsIndependentClass(const std::string& name) {
  return name.rfind("beam_", 0) == 0 || name.rfind("deep_", 0) == 0 || name == "indep_free";
}

AccuracyVolume MakeIndependentAccuracyVolume(const VolumeClass& cls, int index, std::uint64_t seed,
                                             bool next_frame) {
  std::mt19937_64 rng(MixSeed(seed, cls.name, index));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  IndependentVolumeOptions o;
  o.size_voxels = 80;
  o.catheter = cls.catheter;
  o.catheter_angle_deg = cls.catheter ? std::stod(cls.name.substr(5, 2)) : 40.0;
  o.store_image_to_probe = cls.catheter && cls.name.find("_unknown") == std::string::npos;
  o.catheter_azimuth_deg = 360 * u(rng);
  o.tip_offset_mm = Eigen::Vector3d(-3 + 6 * u(rng), -3 + 6 * u(rng), -3 + 6 * u(rng));
  o.seed = rng();
  const bool deep = cls.name.rfind("deep_", 0) == 0;
  double depth_mm = 0;
  if (deep) {
    // The tip 80–100 mm from the apex: the grid lies deeper (the apex further above it).
    SetDeepObliquePhysics(o);
    depth_mm = 80 + 20 * u(rng);
    PlaceTipAtDepth(o, depth_mm);
  }
  IndependentVolume first = MakeIndependentVolume(o);
  char label[160];
  std::snprintf(label, sizeof label, "angle %.0f azimuth %.1f tip offset %.1f %.1f %.1f%s",
                o.catheter_angle_deg, o.catheter_azimuth_deg, o.tip_offset_mm.x(),
                o.tip_offset_mm.y(), o.tip_offset_mm.z(),
                o.store_image_to_probe ? "" : " (no image-to-probe)");
  if (deep) {
    const std::size_t used = std::strlen(label);
    std::snprintf(label + used, sizeof label - used, " tip depth %.1f", depth_mm);
  }
  AccuracyVolume out{std::move(first.volume), first.truth, std::nullopt, std::nullopt, label};
  if (!cls.catheter) out.truth.reset();
  if (next_frame && cls.catheter) {
    o.advance_mm = 1.0;
    o.seed += 1;  // fresh speckle, as a new frame
    IndependentVolume second = MakeIndependentVolume(o);
    out.next_volume = std::move(second.volume);
    out.next_truth = second.truth;
  }
  return out;
}

}  // namespace

const std::vector<VolumeClass>& VolumeClasses() {
  static const std::vector<VolumeClass> classes = {
      {"water_tank",
       "default water-tank scene, reverberation on, 1482 m/s; yaw ±30° (or +180°), tilt 0–15°, tip "
       "depth 50–70 mm, lateral ±5 mm",
       true, false},
      {"no_reverberation", "water_tank poses without the guidewire's comet tail", true, false},
      {"speckle_clutter",
       "background scatter 0.03 (×7.5) and four bright tissue cubes (3–6 mm) 7–10 mm beside the "
       "catheter",
       true, false},
      {"shadowing",
       "water_tank poses with a weakly transmitting plate (T = 0.1) 15 mm above the sheath, "
       "shadowing 15–40 mm behind the tip",
       true, false},
      {"wide_poses",
       "yaw ±60° (or +180°), tilt −5–25°, tip depth 40–80 mm, lateral ±10 mm, advance 0–6 mm", true,
       false},
      {"sound_speed", "water_tank poses in media of 1540, 1600 and 1482 m/s (scanner assumes 1540)",
       true, false},
      {"free_annulus", "catheter-free: annulus and tank", false, false},
      {"free_tank", "catheter-free: tank only", false, false},
      {"free_clutter", "catheter-free: annulus, background scatter 0.03, four bright tissue cubes",
       false, false},
      {"spine_phantom",
       "catheter-free real volume: data/plus/SpinePhantomFreehandReconstructed.mha", false, true},
      {"beam_00", "independent generator: catheter at 0° to the beam, comet tails, known beams",
       true, false},
      {"beam_20", "independent generator: 20° to the beam, comet tails, known beams", true, false},
      {"beam_40", "independent generator: 40° to the beam, comet tails, known beams", true, false},
      {"beam_60", "independent generator: 60° to the beam, comet tails, known beams", true, false},
      {"beam_80", "independent generator: 80° to the beam, comet tails, known beams", true, false},
      {"beam_00_unknown", "beam_00 without an image-to-probe pose (unknown beams)", true, false},
      {"beam_20_unknown", "beam_20 without an image-to-probe pose", true, false},
      {"beam_40_unknown", "beam_40 without an image-to-probe pose", true, false},
      {"beam_60_unknown", "beam_60 without an image-to-probe pose", true, false},
      {"beam_80_unknown", "beam_80 without an image-to-probe pose", true, false},
      {"indep_free",
       "independent generator, catheter-free: speckled blood and a tissue surface, unknown beams",
       false, false},
      {"deep_50",
       "independent generator: 50° to the beam, tip 80–100 mm deep, specular fall-off, "
       "attenuation and TGC, noise, lateral PSF widening with depth, known beams",
       true, false},
      {"deep_56", "deep_50's physics at 56° to the beam (issue 32's miss)", true, false},
      {"deep_60", "deep_50's physics at 60° to the beam", true, false},
      {"deep_70", "deep_50's physics at 70° to the beam", true, false},
      {"deep_80", "deep_50's physics at 80° to the beam", true, false},
      {"deep_free", "deep_50's physics without a catheter (the grid 80–100 mm deep), unknown beams",
       false, false},
  };
  return classes;
}

const VolumeClass& FindVolumeClass(const std::string& name) {
  for (const auto& c : VolumeClasses())
    if (c.name == name) return c;
  std::string known;
  for (const auto& c : VolumeClasses()) {
    if (!known.empty()) known += ", ";
    known += c.name;
  }
  std::string m = "unknown volume class '";
  m += name;
  m += "' (known: ";
  m += known;
  m += ")";
  throw std::invalid_argument(m);
}

AccuracyVolume MakeAccuracyVolume(const VolumeClass& cls, int index, std::uint64_t seed,
                                  bool next_frame, const std::filesystem::path& spine_volume) {
  if (cls.real) {
    if (spine_volume.empty() || !std::filesystem::exists(spine_volume)) {
      std::string m = "spine phantom volume not found: '";
      m += spine_volume.string();
      m += "'";
      throw std::invalid_argument(m);
    }
    return AccuracyVolume{imaging::ReadVolume(spine_volume), std::nullopt, std::nullopt,
                          std::nullopt, spine_volume.filename().string()};
  }
  if (IsIndependentClass(cls.name))
    return MakeIndependentAccuracyVolume(cls, index, seed, next_frame);
  std::mt19937_64 rng(MixSeed(seed, cls.name, index));
  Pose pose;
  const SimulatedScannerOptions o = SceneOptions(cls.name, index, rng, pose);
  imaging::sim::SimulatedScanner scanner(o);
  auto first = scanner.Next();
  AccuracyVolume out{std::move(first->volume), first->truth, std::nullopt, std::nullopt,
                     Label(pose, o)};
  if (next_frame && cls.catheter) {
    scanner.SetCatheterPose({o.catheter_pose.base_to_world, o.catheter_pose.advance_mm + 1.0});
    auto second = scanner.Next();
    out.next_volume = std::move(second->volume);
    out.next_truth = second->truth;
  }
  return out;
}

}  // namespace echoservo::tracking
