#include "live/sim_scene.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "control/trajectory.h"
#include "imaging/sim/catheter_scene.h"
#include "imaging/sim/simulated_scanner.h"

namespace echoservo::live {
namespace {

// The scanner's catheter advance at the plant's tip position 0: the tip then rests 9 mm
// short of the annulus's near face (4–14 mm as it moves ±5 mm), so that following it at
// any standoff from 0 (contact) to 19 mm keeps the plant's tip within its ±15 mm travel.
constexpr double kAdvanceAtZeroMm = 4.5;

}  // namespace

SimScene::SimScene(const SimSceneOptions& o) : o_(o), tip_history_(kTipHistory) {
  imaging::sim::SimulatedScannerOptions so;
  imaging::sim::PlaceCatheterScene({0.0, 10.0, 60.0, 0.0, kAdvanceAtZeroMm}, so);
  so.rate_hz = o.rate_hz;
  so.seed = o.seed;
  char spec[64];
  std::snprintf(spec, sizeof spec, "mitral:%g:%g", o.heart_rate_bpm, o.target_p2p_mm);
  target_motion_ = control::MakeTrajectory(spec);
  const imaging::sim::CatheterPose rest = so.catheter_pose;
  so.catheter_pose_at = [this, rest](double t) {
    imaging::sim::CatheterPose p = rest;
    p.advance_mm = rest.advance_mm + PlantTipAt(t);
    return p;
  };
  so.target_displacement_mm = [this](double t) { return target_motion_->Evaluate(t).position_mm; };
  scanner_ = std::make_unique<imaging::sim::SimulatedScanner>(so);

  const auto& cg = so.catheter_geometry;
  base_to_world_ = rest.base_to_world;
  tip_at_zero_mm_ = rest.advance_mm + cg.sheath_length_mm + cg.wire_protrusion_mm;
  axis_image_ = (scanner_->WorldToImage(base_to_world_ * Eigen::Vector3d(0, 0, 1)) -
                 scanner_->WorldToImage(base_to_world_ * Eigen::Vector3d::Zero()))
                    .normalized();
  displacement_image_ = scanner_->WorldToImage(so.annulus_to_world.linear().col(2)) -
                        scanner_->WorldToImage(Eigen::Vector3d::Zero());
  const imaging::SourceFrame first = scanner_->Render(0.0);
  if (!first.truth || !first.truth->target_visible)
    throw std::logic_error("SimScene: the scene's target is not visible");
  target0_mm_ = first.truth->target_mm;
  d0_mm_ = target_motion_->Evaluate(0.0).position_mm;
  // The scanner's image frame is the world's scaled by depth_scale (uniformly).
  const Eigen::Vector3d base_image = scanner_->WorldToImage(base_to_world_.translation());
  face0_mm_ = (target0_mm_ - base_image).norm() / scanner_->depth_scale();
  if (!(face0_mm_ > tip_at_zero_mm_))
    throw std::logic_error("SimScene: the tissue does not lie ahead of the tip");

  em_options_.image_to_em = Eigen::Translation3d(120.0, -35.0, 210.0) *
                            Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized());
  em_options_.clock_offset_s = 0.0375;
  em_options_.seed = o.seed + 11;
}

SimScene::~SimScene() = default;

void SimScene::SetPlantTip(double t_s, double tip_mm) {
  std::unique_lock lock(tip_m_, std::try_to_lock);
  if (!lock.owns_lock()) {                    // a reader has it: keep the sample for the next call
    if (tip_pending_count_ == kTipPending) {  // drop the oldest kept sample
      std::move(tip_pending_.begin() + 1, tip_pending_.end(), tip_pending_.begin());
      --tip_pending_count_;
    }
    tip_pending_[tip_pending_count_++] = {t_s, tip_mm};
    return;
  }
  for (std::size_t i = 0; i < tip_pending_count_; ++i)
    AddTipLocked(tip_pending_[i].first, tip_pending_[i].second);
  tip_pending_count_ = 0;
  AddTipLocked(t_s, tip_mm);
}

void SimScene::AddTipLocked(double t_s, double tip_mm) {
  const std::size_t n = tip_history_.size();
  auto at = [&](std::size_t i) -> std::pair<double, double>& {
    return tip_history_[(tip_first_ + i) % n];
  };
  if (tip_count_ > 0 && t_s <= at(tip_count_ - 1).first) return;  // out of order: ignored
  if (tip_count_ == n) {                                          // full: the oldest goes
    tip_first_ = (tip_first_ + 1) % n;
    --tip_count_;
  }
  at(tip_count_++) = {t_s, tip_mm};
  while (tip_count_ > 2 && at(0).first < t_s - 1.0) {
    tip_first_ = (tip_first_ + 1) % n;
    --tip_count_;
  }
}

double SimScene::PlantTipAt(double t_s) const {
  std::lock_guard lock(tip_m_);
  if (tip_count_ == 0) return 0.0;
  const std::size_t n = tip_history_.size();
  auto at = [&](std::size_t i) -> const std::pair<double, double>& {
    return tip_history_[(tip_first_ + i) % n];
  };
  if (t_s <= at(0).first) return at(0).second;
  if (t_s >= at(tip_count_ - 1).first) return at(tip_count_ - 1).second;
  std::size_t lo = 0, hi = tip_count_ - 1;  // at(lo).t < t_s ≤ at(hi).t
  while (hi - lo > 1) {
    const std::size_t mid = lo + (hi - lo) / 2;
    (at(mid).first < t_s ? lo : hi) = mid;
  }
  const double f = (t_s - at(lo).first) / (at(hi).first - at(lo).first);
  return at(lo).second + f * (at(hi).second - at(lo).second);
}

imaging::SourceFrame SimScene::Render(double t_s) { return scanner_->Render(t_s); }

Eigen::Vector3d SimScene::TipImage(double plant_tip_mm) const {
  return scanner_->WorldToImage(base_to_world_ *
                                Eigen::Vector3d(0, 0, tip_at_zero_mm_ + plant_tip_mm));
}

Eigen::Vector3d SimScene::TargetImage(double t_s) const {
  return target0_mm_ + (target_motion_->Evaluate(t_s).position_mm - d0_mm_) * displacement_image_;
}

double SimScene::TipPastSurfaceMm(double t_s) const {
  const double face = face0_mm_ + target_motion_->Evaluate(t_s).position_mm - d0_mm_;
  return tip_at_zero_mm_ + PlantTipAt(t_s) - face;
}

Eigen::Vector3d SimScene::DesiredTip(double t_s) const {
  return TargetImage(t_s) - o_.standoff_mm * axis_image_;
}

}  // namespace echoservo::live
