// The simulated water tank of the live demo and of `echoservo track --sim`: the simulated
// scanner's scene (the default catheter pose, the annulus moving along its normal with the
// mitral trajectory), the catheter advanced to the simulated plant's tip, which the servo
// side reports (SetPlantTip) — that is what closes the loop —, and the ground truth the
// figures need, in the image frame: the true tip for a plant tip position, the target, and
// where the tip should be (the target less the standoff along the catheter axis).
// Contact: the tissue is compliant and the tip indents it locally. The scanner renders the
// tissue moving by its own motion, undeformed, so a tip pressed into it shows as the wire
// within the tissue past its surface (TipPastSurfaceMm, the indentation's depth), while the
// surface around the tip stays where the tissue's motion puts it; the target (TargetImage,
// and the scanner's per-volume truth: where the axis meets that surface) and DesiredTip
// are that surface's, so pressing into the tissue counts as tip error.
// Units: mm, s (pipeline clock), image frame.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "hw/sim_em_tracker.h"
#include "imaging/volume_source.h"

namespace echoservo::control {
class Trajectory;
}
namespace echoservo::imaging::sim {
class SimulatedScanner;
}

namespace echoservo::live {

struct SimSceneOptions {
  double rate_hz = 25.0;         // volume rate
  double heart_rate_bpm = 60.0;  // the target's mitral trajectory
  double target_p2p_mm = 10.0;
  double standoff_mm = 8.0;  // for DesiredTip
  std::uint64_t seed = 1;
};

class SimScene {
 public:
  // Throws std::logic_error when the scene's target is not visible (a scene bug).
  explicit SimScene(const SimSceneOptions& options);
  ~SimScene();
  SimScene(const SimScene&) = delete;
  SimScene& operator=(const SimScene&) = delete;

  // The plant's tip position (catheter coordinates, mm) at t_s (pipeline clock), in time
  // order; the scene shows the tip at each volume's acquisition time, interpolated in
  // this history (the last second is kept, up to kTipHistory samples), not where it is
  // when rendering starts. One writer thread at a time (the demo's servo thread): it never
  // waits for the readers (the renderer, the tracker) and never allocates — a sample that
  // finds the history in use is kept aside (up to kTipPending) and added by the next call.
  void SetPlantTip(double t_s, double tip_mm);
  static constexpr std::size_t kTipHistory = 4096, kTipPending = 64;
  double PlantTipAt(double t_s) const;
  // The volume acquired at t_s (one rendering thread).
  imaging::SourceFrame Render(double t_s);

  Eigen::Vector3d TipImage(double plant_tip_mm) const;
  Eigen::Vector3d TargetImage(double t_s) const;
  Eigen::Vector3d DesiredTip(double t_s) const;
  // How far the tip lies past the tissue's surface along the axis at t_s (world mm; > 0: the
  // tip indents the tissue, < 0: the gap ahead of it).
  double TipPastSurfaceMm(double t_s) const;
  const Eigen::Vector3d& axis_image() const { return axis_image_; }

  // The simulated EM tracker on the tip: its own frame (image_to_em) and clock offset.
  const hw::SimEmTrackerOptions& em_options() const { return em_options_; }
  Eigen::Isometry3d em_to_image() const { return em_options_.image_to_em.inverse(); }

 private:
  SimSceneOptions o_;
  void AddTipLocked(double t_s, double tip_mm);
  mutable std::mutex tip_m_;
  // (t_s, tip_mm), a ring of kTipHistory: entry i (0 oldest) at (tip_first_ + i) % size.
  std::vector<std::pair<double, double>> tip_history_;
  std::size_t tip_first_ = 0, tip_count_ = 0;
  std::array<std::pair<double, double>, kTipPending> tip_pending_{};  // writer thread only
  std::size_t tip_pending_count_ = 0;
  std::unique_ptr<control::Trajectory> target_motion_;
  std::unique_ptr<imaging::sim::SimulatedScanner> scanner_;
  Eigen::Isometry3d base_to_world_ = Eigen::Isometry3d::Identity();
  double tip_at_zero_mm_ = 0.0;  // tip's distance from the base along the axis at plant tip 0
  Eigen::Vector3d axis_image_ = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d displacement_image_ = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d target0_mm_ = Eigen::Vector3d::Zero();
  double d0_mm_ = 0.0;
  // The tissue's near face on the axis at displacement d0_mm_, from the base (world mm).
  double face0_mm_ = 0.0;
  hw::SimEmTrackerOptions em_options_;
};

}  // namespace echoservo::live
