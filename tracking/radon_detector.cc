#include "tracking/radon_detector.h"

#include "tracking/axis_profile.h"
#include "tracking/radon_transform.h"
#include "tracking/tube_check.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

namespace echoservo::tracking {
namespace {

double MedianNonZero(const imaging::Volume& v) {
  std::array<std::int64_t, 256> h{};
  for (auto x : v.voxels()) ++h[x];
  std::int64_t n = 0;
  for (int i = 1; i < 256; ++i) n += h[static_cast<std::size_t>(i)];
  if (n == 0) return 0.0;
  std::int64_t acc = 0;
  for (int i = 1; i < 256; ++i) {
    acc += h[static_cast<std::size_t>(i)];
    if (2 * acc >= n) return i;
  }
  return 255.0;
}

double RobustZ(std::vector<double> sc, double score) {
  if (sc.empty()) return 0.0;
  auto mid = sc.begin() + static_cast<long>(sc.size() / 2);
  std::nth_element(sc.begin(), mid, sc.end());
  const double med = *mid;
  for (auto& x : sc) x = std::abs(x - med);
  std::nth_element(sc.begin(), mid, sc.end());
  const double mad = 1.4826 * (*mid);
  return (score - med) / (mad + 1e-3 * score + 1e-12);
}

}  // namespace

void RadonDetectorOptions::Validate() const {
  auto bad = [](const std::string& f) { throw std::invalid_argument("RadonDetectorOptions: bad " + f); };
  if (coarse_factor < 2 || coarse_factor > 16) bad("coarse_factor");
  if (coarse_directions < 16 || coarse_directions > 100000) bad("coarse_directions");
  if (!(fine_cone_rad > 0 && fine_cone_rad < 1)) bad("fine_cone_rad");
  if (fine_steps < 2 || fine_steps > 101) bad("fine_steps");
  fit.Validate();
  tube.Validate();
  if (!(edge.edge_fraction > 0 && edge.edge_fraction < 1)) bad("edge.edge_fraction");
  if (!(edge.dynamic_range_db > 0 && edge.dynamic_range_db <= 120)) bad("edge.dynamic_range_db");
  if (!(min_line_length_mm >= 0 && std::isfinite(min_line_length_mm))) bad("min_line_length_mm");
  if (!(min_confidence >= 0 && min_confidence <= 1)) bad("min_confidence");
  if (!(tracking_cone_rad > 0 && tracking_cone_rad < 1.5)) bad("tracking_cone_rad");
  if (!(tracking_window_mm > 0 && std::isfinite(tracking_window_mm))) bad("tracking_window_mm");
  if (!(max_depth_fraction > 0 && max_depth_fraction <= 1)) bad("max_depth_fraction");
  if (!(max_spacing_ratio >= 1 && std::isfinite(max_spacing_ratio))) bad("max_spacing_ratio");
}

RadonDetector::RadonDetector(RadonDetectorOptions options) : options_(std::move(options)) {
  options_.Validate();
}

CatheterDetection RadonDetector::Detect(const imaging::Volume& volume) const {
  return Run(volume, nullptr);
}

CatheterDetection RadonDetector::Detect(const imaging::Volume& volume, const Line3& previous) const {
  auto r = Run(volume, &previous);
  if (r.found && r.confidence >= options_.min_confidence) return r;
  return Run(volume, nullptr);
}

CatheterDetection RadonDetector::Track(const imaging::Volume& volume) {
  auto r = previous_ ? Detect(volume, *previous_) : Detect(volume);
  if (r.found) previous_ = r.axis; else previous_.reset();
  return r;
}

CatheterDetection RadonDetector::Run(const imaging::Volume& v, const Line3* previous) const {
  CatheterDetection out;
  const Eigen::Vector3d sp = v.spacing_mm();
  if (sp.maxCoeff() > options_.max_spacing_ratio * sp.minCoeff())
    throw std::invalid_argument("RadonDetector: voxel spacing too anisotropic (max/min > " +
                                std::to_string(options_.max_spacing_ratio) + ")");
  if (v.dims().minCoeff() < 8) return out;
  const double bg = MedianNonZero(v);

  const int f1 = options_.coarse_factor, f2 = std::max(1, f1 / 2);
  const RadonLevel L1 = MakeRadonLevel(v, f1, options_.max_depth_fraction);
  if (L1.cells.size() < 4) return out;
  const RadonLevel L2 = MakeRadonLevel(v, f2, options_.max_depth_fraction);

  RadonSearchResult b;
  RadonWindow window_storage;
  const RadonWindow* window = nullptr;
  if (previous) {
    window_storage = RadonWindow{*previous, options_.tracking_window_mm};
    window = &window_storage;
    Eigen::Vector3d pd = previous->direction;
    if (pd.z() < 0) pd = -pd;
    const int steps = std::max(3, static_cast<int>(std::ceil(2 * options_.tracking_cone_rad / 0.03)) | 1);
    b = SearchDirections(L1, DirectionCone(pd, options_.tracking_cone_rad, steps), window);
  } else {
    b = SearchDirections(L1, FibonacciHemisphere(options_.coarse_directions), nullptr);
  }
  if (b.peak.score <= 0) return out;
  // Refine at the finer level, near the coarse line.
  RadonWindow near{PeakLine(L1, b.direction, b.peak), 2 * L1.bin_mm};
  double cone = options_.fine_cone_rad;
  RadonSearchResult f = b;
  for (int pass = 0; pass < 2; ++pass) {
    RadonSearchResult g = SearchDirections(L2, DirectionCone(f.direction, cone, options_.fine_steps), &near);
    if (g.peak.score > 0) {
      f = g;
      near.line = PeakLine(L2, f.direction, f.peak);
    }
    cone /= (options_.fine_steps - 1) / 2.0;
  }
  // Shallowest strong line among the parallel candidates of the best direction.
  auto peaks = RadonPeaks(L2, f.direction, window, true);
  if (peaks.empty()) return out;
  // The distribution of line scores over the hemisphere (a sparse set when tracking: the
  // cone's directions all see the line).
  const double z_score =
      RobustZ(previous ? SearchDirections(L1, FibonacciHemisphere(std::max(16, options_.coarse_directions / 8)),
                                          nullptr).scores
                       : b.scores,
              b.peak.score);
  Line3 line = PeakLine(L2, f.direction, peaks.front());
  for (const auto& p : peaks) {
    if (p.score < 0.6 * peaks.front().score) break;
    const Line3 cand = PeakLine(L2, f.direction, p);
    if (cand.point.z() < line.point.z() - 1.0 && std::abs(cand.point.z() - line.point.z()) < 15.0) line = cand;
  }

  const auto fit = FitEchoAxis(v, line, bg, options_.fit);
  if (!fit) return out;
  const TipEstimate tip = FindTip(v, fit->axis, bg, options_.edge);
  if (!tip.found) return out;
  out.axis = tip.axis;
  out.tip_mm = tip.tip_mm;
  out.line_length_mm = tip.line_length_mm;
  const TargetEstimate target = FindTarget(v, tip, bg, options_.edge);
  out.target_found = target.found;
  out.target_mm = target.target_mm;

  out.tubularity = Tubularity(v, out.axis, out.axis.Parameter(out.tip_mm) - out.line_length_mm,
                              out.axis.Parameter(out.tip_mm), options_.edge.dynamic_range_db, options_.tube);

  // Confidence: Radon peak contrast (robust z among the directions' best lines), length, and
  // the line's tube shape (a line within a surface is not a catheter).
  const double c_peak = 1.0 - std::exp(-std::max(0.0, z_score - 10.0) / 8.0);
  const double c_len = std::clamp(out.line_length_mm / (2.0 * std::max(1e-9, options_.min_line_length_mm)), 0.0, 1.0);
  const double c_tube = std::clamp((out.tubularity - 0.2) / 0.5, 0.0, 1.0);
  out.confidence = std::clamp(c_peak * c_len * c_tube, 0.0, 1.0);
  out.tracked = previous != nullptr;
  out.found = out.confidence >= options_.min_confidence && out.line_length_mm >= options_.min_line_length_mm;
  out.peak_z = z_score;
  return out;
}

}  // namespace echoservo::tracking
