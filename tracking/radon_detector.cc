#include "tracking/radon_detector.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "tracking/axis_profile.h"
#include "tracking/radon_transform.h"
#include "tracking/tube_check.h"

namespace echoservo::tracking {
namespace {

// The fine refinement's second stage searches next to this many of its first stage's best
// directions (SearchConeCoarseToFine).
constexpr int kFineTopK = 3;
// The axis is fitted again on the echoes up to this far beyond the first tip, and that fit
// kept when it turns the axis by more than kRefitMinTurnRad (1°) (EvaluateLine).
// The refit runs only when the fit's echoes reach more than kFitReachMarginMm farther.
constexpr double kFitBeyondTipMm = 1.0;
constexpr double kFitReachMarginMm = 1.0;
constexpr double kRefitMinTurnRad = 0.01745;

// Median and MAD of line scores into scene.score_median / score_mad; false when empty.
bool SetScoreStats(std::vector<double> sc, SceneBaseline& scene) {
  if (sc.empty()) return false;
  const MedianMad m = ComputeMedianMad(sc);
  scene.score_median = m.median;
  scene.score_mad = m.mad;
  return true;
}

// The confidence's Radon-peak factor from the peak's robust z-score (EvaluateLine): the peak's
// contrast only needs to be clear (z ≥ 5).
double PeakConfidence(double z_score) {
  return 1.0 - std::exp(-std::max(0.0, z_score - 5.0) / 4.0);
}

// Robust z-score of `score` among the scene's line scores.
double RobustZ(const SceneBaseline& scene, double score) {
  return (score - scene.score_median) / (1.4826 * scene.score_mad + 1e-3 * score + 1e-12);
}

// The z-score against the rest of the scene. A full search's per-direction best lines mostly
// lie on the brightest object (measured on the independent generator's catheters: 63–88 % of
// the first stage's directions pass within kOwnEchoMm of the catheter), so the baseline grows
// with that object's echo: the z-score says how much more the object scores along the line
// than seen from the side. A catheter whose sheath has lost its specular echo (50–80° to the
// beam) while its short guidewire stays bright looks compact from the side, and its z falls
// to 4–8 (below the 7.8 that c_peak = 0.5 needs); against the directions whose best line
// does not meet it, it measures 10–43. A compact reflector (a tissue cube) gains too (5.6 →
// 9.0 measured), so this z counts only when the whole hemisphere's is not enough and the
// bright run is long (RadonDetector::EvaluateLine).
// Two lines "meet" when they pass within kOwnEchoMm of each other inside the volume's box
// (grown by that much).
constexpr double kOwnEchoMm = 3.0;
// At least this fraction of the directions (and 24) must remain for the rest's statistics.
constexpr double kMinRestFraction = 0.1;

bool LinesMeet(const Line3& a, const Line3& b, const Eigen::AlignedBox3d& box, double r) {
  const Eigen::Vector3d da = a.direction.normalized(), db = b.direction.normalized();
  const Eigen::Vector3d w0 = a.point - b.point;
  const double ab = da.dot(db), den = 1.0 - ab * ab;
  if (den < 1e-9) return (w0 - w0.dot(da) * da).norm() < r;  // parallel
  const double s = (ab * db.dot(w0) - da.dot(w0)) / den;
  const double t = db.dot(w0) + s * ab;
  const Eigen::Vector3d pa = a.point + s * da, pb = b.point + t * db;
  return (pa - pb).norm() < r && box.exteriorDistance(pa) <= r;
}

// The scene's line-score statistics over the search's directions whose best line does not
// meet `line`; invalid when too few remain.
SceneBaseline RestOfScene(const SceneBaseline& scene, const RadonSearchResult& b,
                          const RadonLevel& level, const Line3& line,
                          const Eigen::AlignedBox3d& box) {
  SceneBaseline rest = scene;
  rest.valid = false;
  std::vector<double> sc;
  sc.reserve(b.scores.size());
  for (std::size_t i = 0; i < b.scores.size() && i < b.peaks.size(); ++i)
    if (!LinesMeet(line, PeakLine(level, b.directions[i], b.peaks[i]), box, kOwnEchoMm))
      sc.push_back(b.scores[i]);
  if (sc.size() < 24 ||
      static_cast<double>(sc.size()) < kMinRestFraction * static_cast<double>(b.scores.size()))
    return rest;
  rest.valid = SetScoreStats(std::move(sc), rest);
  rest.scores_without_line = true;
  return rest;
}

// The search's two Radon levels, and the whole volume's coarse grid when it was pooled.
struct SearchLevels {
  std::optional<PooledGrid> coarse_grid;
  RadonLevel coarse, fine;
};

// Levels measured on `v`, the scene's intensity levels with them. The volume is read once:
// the fine grid, pooled again, is the coarse grid (max of maxima).
SearchLevels MeasuredLevels(const imaging::Volume& v, const RadonDetectorOptions& o,
                            const RadonWindow* roi, SceneBaseline& scene) {
  const int f1 = o.coarse_factor, f2 = std::max(1, f1 / 2);
  scene.voxel_background = MedianNonZeroVoxel(v);
  const PooledGrid fine_grid = MaxPool(v, f2);
  SearchLevels L;
  L.coarse_grid = f1 % f2 == 0 ? MaxPool(fine_grid, f1 / f2) : MaxPool(v, f1);
  scene.coarse = GridThresholds(*L.coarse_grid, o.level_min_contrast);
  scene.fine = GridThresholds(fine_grid, o.level_min_contrast);
  L.coarse = MakeRadonLevel(v, *L.coarse_grid, o.max_depth_fraction, roi, scene.coarse);
  L.fine = MakeRadonLevel(v, fine_grid, o.max_depth_fraction, roi, scene.fine);
  return L;
}

// Levels of the tracking region alone, with the scene's known intensity levels: only the
// voxels near the previous axis are read.
SearchLevels TrackingLevels(const imaging::Volume& v, const RadonDetectorOptions& o,
                            const RadonWindow& roi, const SceneBaseline& scene) {
  const int f1 = o.coarse_factor, f2 = std::max(1, f1 / 2);
  SearchLevels L;
  // One region for both levels: the fine level is read for the refinement near the coarse
  // line (up to 2 coarse bins beyond the window) and for the peaks within the window, each
  // with its ring and footprint — as far out as the coarse level's margin reaches.
  // The volume is read once: the coarse cells' blocks, pooled at the fine factor, then again.
  if (f1 % f2 == 0) {
    const NestedGrids g = MaxPoolNested(v, f2, f1 / f2, roi);
    L.coarse = MakeRadonLevel(v, g.coarse, o.max_depth_fraction, &roi, scene.coarse);
    L.fine = MakeRadonLevel(v, g.fine, o.max_depth_fraction, &roi, scene.fine);
    return L;
  }
  L.coarse = MakeRadonLevel(v, MaxPool(v, f1, roi), o.max_depth_fraction, &roi, scene.coarse);
  L.fine = MakeRadonLevel(v, MaxPool(v, f2, roi), o.max_depth_fraction, &roi, scene.fine);
  return L;
}

}  // namespace

void RadonDetectorOptions::Validate() const {
  auto bad = [](const std::string& f) {
    throw std::invalid_argument("RadonDetectorOptions: bad " + f);
  };
  if (coarse_factor < 2 || coarse_factor > 16) bad("coarse_factor");
  params::kCoarseDirections.Check(coarse_directions, "RadonDetectorOptions");
  if (hemisphere_search.stride < 1 || hemisphere_search.stride > 64)
    bad("hemisphere_search.stride");
  if (hemisphere_search.top_k < 1 || hemisphere_search.top_k > 256) bad("hemisphere_search.top_k");
  if (!(hemisphere_search.neighbour_rad > 0 && hemisphere_search.neighbour_rad < 1.6))
    bad("hemisphere_search.neighbour_rad");
  if (!(fine_cone_rad > 0 && fine_cone_rad < 1)) bad("fine_cone_rad");
  if (fine_steps < 2 || fine_steps > 101) bad("fine_steps");
  fit.Validate();
  tube.Validate();
  params::kEdgeFraction.Check(edge.edge_fraction, "RadonDetectorOptions");
  params::kDynamicRangeDb.Check(edge.dynamic_range_db, "RadonDetectorOptions");
  params::kTipFirstEchoMm.Check(edge.tip_first_echo_mm, "RadonDetectorOptions");
  params::kLateralRadiusMm.Check(edge.lateral_radius_mm, "RadonDetectorOptions");
  if (!(edge.lateral_back_mm >= 3 && edge.lateral_back_mm <= 30)) bad("edge.lateral_back_mm");
  params::kCloseGapMm.Check(edge.close_gap_mm, "RadonDetectorOptions");
  params::kContactGapMm.Check(edge.contact_gap_mm, "RadonDetectorOptions");
  if (!(edge.contact_gap_mm < edge.close_gap_mm)) bad("edge.contact_gap_mm (< edge.close_gap_mm)");
  if (!(edge.doubt_gap_mm >= 0 && edge.doubt_gap_mm < edge.close_gap_mm)) bad("edge.doubt_gap_mm");
  if (!(min_line_length_mm >= 0 && std::isfinite(min_line_length_mm))) bad("min_line_length_mm");
  params::kMinConfidence.Check(min_confidence, "RadonDetectorOptions");
  params::kTrackingConeRad.Check(tracking_cone_rad, "RadonDetectorOptions");
  params::kTrackingWindowMm.Check(tracking_window_mm, "RadonDetectorOptions");
  if (!(max_depth_fraction > 0 && max_depth_fraction <= 1)) bad("max_depth_fraction");
  if (!(max_spacing_ratio >= 1 && std::isfinite(max_spacing_ratio))) bad("max_spacing_ratio");
  if (!(level_min_contrast >= 0 && level_min_contrast < 1)) bad("level_min_contrast");
  if (max_candidates < 1 || max_candidates > 16) bad("max_candidates");
  if (!(candidate_separation_rad > 0 && candidate_separation_rad < 1.6))
    bad("candidate_separation_rad");
  if (beams) {
    if (!beams->apex_mm.allFinite()) bad("beams.apex_mm (must be finite)");
    if (!beams->axis.allFinite()) bad("beams.axis (must be finite)");
    if (beams->kind == BeamGeometry::Kind::kParallel && !(beams->axis.norm() > 1e-9))
      bad("beams.axis (a parallel beam needs a non-zero direction)");
  }
}

RadonDetector::RadonDetector(RadonDetectorOptions options) : options_(std::move(options)) {
  options_.Validate();
}

CatheterDetection RadonDetector::Detect(const imaging::Volume& volume) const {
  return Run(volume, nullptr, nullptr);
}

CatheterDetection RadonDetector::Detect(const imaging::Volume& volume,
                                        const Line3& previous) const {
  auto r = Run(volume, &previous, nullptr);
  if (r.found && r.confidence >= options_.min_confidence) return r;
  return Run(volume, nullptr, nullptr);
}

CatheterDetection RadonDetector::Detect(const imaging::Volume& volume,
                                        const CatheterDetection& previous) const {
  if (!previous.found) return Run(volume, nullptr, nullptr);
  auto r = Run(volume, &previous.axis, &previous.baseline);
  if (r.found && r.confidence >= options_.min_confidence) return r;
  return Run(volume, nullptr, nullptr);
}

CatheterDetection RadonDetector::Track(const imaging::Volume& volume) {
  auto r = previous_ ? Detect(volume, *previous_) : Detect(volume);
  if (r.found)
    previous_ = r;
  else
    previous_.reset();
  return r;
}

CatheterDetection RadonDetector::Run(const imaging::Volume& v, const Line3* previous,
                                     const SceneBaseline* known) const {
  CatheterDetection out;
  const Eigen::Vector3d sp = v.spacing_mm();
  if (sp.maxCoeff() > options_.max_spacing_ratio * sp.minCoeff())
    throw std::invalid_argument("RadonDetector: voxel spacing too anisotropic (max/min > " +
                                std::to_string(options_.max_spacing_ratio) + ")");
  if (v.dims().minCoeff() < 8) return out;

  // Tracking searches lines near the previous axis only, so the levels keep the cells of a
  // cylinder around it: the offset window, plus the ring (2 coarse bins) and the bilinear
  // footprint (1 bin) of a peak at the window's edge, plus a bin for the cone's tilt.
  std::optional<RadonWindow> roi;
  if (previous)
    roi = RadonWindow{
        Line3{previous->point, previous->direction.normalized()},
        options_.tracking_window_mm + 4 * options_.coarse_factor * std::cbrt(sp.prod())};
  // A tracked frame reuses the scene's statistics of the frame it started from (only the
  // tracking region is read); otherwise they are measured on this volume.
  SceneBaseline scene = known && known->valid ? *known : SceneBaseline{};
  const SearchLevels levels = scene.valid && roi
                                  ? TrackingLevels(v, options_, *roi, scene)
                                  : MeasuredLevels(v, options_, roi ? &*roi : nullptr, scene);
  out.baseline = scene;
  const double bg = scene.voxel_background;
  const RadonLevel& L1 = levels.coarse;
  const RadonLevel& L2 = levels.fine;
  if (L1.cells.size() < 4) return out;

  RadonSearchResult b;
  // The refinement: a full search's directions are ~3° apart, so two passes from
  // fine_cone_rad; tracking's cone grid is already 1.6° fine, so one pass within a spacing.
  FineSearch fine{options_.fine_cone_rad, 2, options_.fine_steps};
  RadonWindow window_storage;
  const RadonWindow* window = nullptr;
  if (previous) {
    window_storage = RadonWindow{*previous, options_.tracking_window_mm};
    window = &window_storage;
    Eigen::Vector3d pd = previous->direction;
    if (pd.z() < 0) pd = -pd;
    const int steps =
        std::max(3, static_cast<int>(std::ceil(2 * options_.tracking_cone_rad / 0.03)) | 1);
    // Coarse to fine over the cone's grid too (every other row and column, then the rest
    // next to its best directions): only the best line is used here.
    const double spacing_rad = 2 * options_.tracking_cone_rad / (steps - 1);
    fine = FineSearch{spacing_rad, 1, 5};
    b = SearchConeCoarseToFine(L1, pd, options_.tracking_cone_rad, steps, 4, window);
  } else {
    // Coarse to fine over the hemisphere: every fifth direction, then the rest near the best
    // of those (the same best line at ~35 % of the cost; the z-score's baseline is the first
    // stage's scores, a uniform fifth of the hemisphere's).
    b = SearchDirectionsCoarseToFine(L1, FibonacciHemisphere(options_.coarse_directions),
                                     options_.hemisphere_search);
  }
  if (b.peak.score <= 0) return out;
  // A full search's own scores: each candidate is also measured against the rest of the scene
  // (RestOfScene).
  const bool own_scores = !previous && !scene.valid;
  // The distribution of line scores over the hemisphere, unless known: a full search's own
  // scores, or, when tracking, a sparse set on the whole coarse level (the cone's
  // directions all see the line, and the tracking region holds little else).
  if (!scene.valid) {
    const bool have_scores =
        previous
            ? SetScoreStats(
                  SearchDirections(
                      MakeRadonLevel(v, *levels.coarse_grid, options_.max_depth_fraction, nullptr,
                                     scene.coarse),
                      FibonacciHemisphere(std::max(16, options_.coarse_directions / 8)), nullptr)
                      .scores,
                  scene)
            : SetScoreStats(b.scores, scene);
    scene.valid = have_scores;
  }
  out.baseline = scene;
  // The best line first; when it is not a catheter (a line within a surface fails the tube
  // check) a full search tries the runners-up: the best first-stage directions at least
  // `candidate_separation_rad` from every direction tried, scoring at least half the best.
  CatheterDetection best = out;
  std::vector<Eigen::Vector3d> tried;
  const double cos_sep = std::cos(options_.candidate_separation_rad);
  std::vector<std::size_t> order;  // the runners-up by score, sorted when first needed
  std::size_t next = 0;
  for (int c = 0; c < (previous ? 1 : options_.max_candidates); ++c) {
    Eigen::Vector3d dir = b.direction;
    RadonPeak peak = b.peak;
    if (c > 0) {
      if (order.empty()) {
        order.resize(b.scores.size());
        std::iota(order.begin(), order.end(), std::size_t{0});
        std::sort(order.begin(), order.end(),
                  [&](std::size_t x, std::size_t y) { return b.scores[x] > b.scores[y]; });
      }
      while (next < order.size() && b.scores[order[next]] >= 0.5 * b.peak.score &&
             std::any_of(tried.begin(), tried.end(), [&](const Eigen::Vector3d& t) {
               return std::abs(t.dot(b.directions[order[next]])) >= cos_sep;
             }))
        ++next;
      if (next >= order.size() || b.scores[order[next]] < 0.5 * b.peak.score) break;
      dir = b.directions[order[next]];
      peak = b.peaks[order[next]];
    }
    tried.push_back(dir);
    const SceneBaseline rest =
        own_scores && scene.valid
            ? RestOfScene(scene, b, L1, PeakLine(L1, dir, peak), v.BoundingBoxMm())
            : SceneBaseline{};
    // The confidence is a product of factors ≤ 1: a line whose peak factor alone is below
    // min_confidence cannot be found, and is not evaluated (a catheter-free volume's
    // runners-up, usually).
    const double z = scene.valid ? std::max(RobustZ(scene, peak.score),
                                            rest.valid ? RobustZ(rest, peak.score) : 0.0)
                                 : 0.0;
    if (scene.valid && options_.min_confidence > 0 && PeakConfidence(z) < options_.min_confidence) {
      if (c == 0) {
        best.peak_z = z;
        best.tracked = previous != nullptr;
      }
      continue;
    }
    CatheterDetection d =
        EvaluateLine(v, L1, L2, dir, peak, fine, window, bg, scene, rest.valid ? &rest : nullptr);
    d.tracked = previous != nullptr;
    if (d.found) return d;
    if (c == 0 || d.confidence > best.confidence) best = d;
  }
  return best;
}

CatheterDetection RadonDetector::EvaluateLine(const imaging::Volume& v, const RadonLevel& L1,
                                              const RadonLevel& L2,
                                              const Eigen::Vector3d& direction,
                                              const RadonPeak& coarse_peak, const FineSearch& fine,
                                              const RadonWindow* window, double bg,
                                              const SceneBaseline& scene,
                                              const SceneBaseline* rest) const {
  CatheterDetection out;
  out.baseline = scene;
  // Refine at the finer level, near the coarse line.
  RadonWindow near{PeakLine(L1, direction, coarse_peak), 2 * L1.bin_mm};
  double cone = fine.cone_rad;
  RadonSearchResult f;
  f.direction = direction;
  f.peak = coarse_peak;
  for (int pass = 0; pass < fine.passes; ++pass) {
    RadonSearchResult g =
        SearchConeCoarseToFine(L2, f.direction, cone, fine.steps, kFineTopK, &near);
    if (g.peak.score > 0) {
      f = g;
      near.line = PeakLine(L2, f.direction, f.peak);
    }
    cone /= (fine.steps - 1) / 2.0;
  }
  // Nearest the transducer among the strong parallel lines of the best direction: comet
  // tails (reverberation) lie behind the catheter along the beam, so farther from the probe
  // apex (or deeper along a parallel beam). Unknown beams: the strongest line.
  auto peaks = RadonPeaks(L2, f.direction, window, false);
  if (peaks.empty()) return out;
  const double z_score = scene.valid ? RobustZ(scene, coarse_peak.score) : 0.0;
  BeamGeometry beams = options_.beams ? *options_.beams : BeamGeometry::FromVolume(v);
  // Range from the transducer: distance to the apex, or depth along a parallel beam.
  auto range_of = [&](const Line3& l) {
    if (beams.kind == BeamGeometry::Kind::kParallel)
      return (l.point - l.point.dot(l.direction) * l.direction).dot(beams.axis);
    return PointToLineDistance(l, beams.apex_mm);
  };
  Line3 line = PeakLine(L2, f.direction, peaks.front());
  if (beams.known()) {
    double range = range_of(line);
    for (const auto& p : peaks) {
      if (p.score < 0.6 * peaks.front().score) break;
      const Line3 cand = PeakLine(L2, f.direction, p);
      const double r = range_of(cand);
      if (r < range - 1.0 && range - r < 15.0) {
        line = cand;
        range = r;
      }
    }
  }

  // Tracking with the beams its full search inferred: the fit with them at once.
  const bool volume_beams_known = beams.known();
  const bool reuse_beams = window && !beams.known() && options_.infer_beams_from_ribbon &&
                           scene.inferred_beams.has_value();
  if (reuse_beams) beams = *scene.inferred_beams;
  auto fit = FitEchoAxis(v, line, bg, options_.fit, beams);
  if (!fit) return out;
  // FindTip's first-echo edge looks back along the volume's own beams: only when those are
  // the beams in use.
  EdgeOptions tip_edge = options_.edge;
  if (options_.beams || !volume_beams_known) tip_edge.tip_first_echo_mm = 0.0;
  TipEstimate tip = FindTip(v, fit->axis, bg, tip_edge);
  if (!tip.found) return out;
  // The ribbon looked for along the tip's axis, [s_from, s_to], and what was found: the tube
  // check below does not look again over the same range.
  struct {
    bool looked = false;
    double s_from = 0, s_to = 0;
    std::optional<Eigen::Vector3d> direction;
  } ribbon;
  if (!beams.known() && options_.infer_beams_from_ribbon) {
    // Unknown beams, but a single view's reverberation ribbon shows where they point (its
    // direction ⟂ the axis, away from the transducer): then the near-wall model and the
    // first-echo rule apply with those beams. No ribbon (a compounded volume, a catheter
    // along the beam): the symmetric centre-line fit stands.
    const double s_tip = tip.axis.Parameter(tip.tip_mm);
    ribbon.looked = true;
    ribbon.s_from = s_tip - tip.line_length_mm;
    ribbon.s_to = s_tip;
    ribbon.direction = RibbonDirection(v, tip.axis, ribbon.s_from, ribbon.s_to,
                                       options_.edge.dynamic_range_db, options_.tube);
    if (const auto& e = ribbon.direction) {
      const BeamGeometry inferred = BeamGeometry::Parallel(*e);
      auto refit = FitEchoAxis(v, fit->axis, bg, options_.fit, inferred);
      if (refit) {
        const TipEstimate retip = FindTip(v, refit->axis, bg, tip_edge);
        if (retip.found) {
          fit = std::move(refit);
          tip = retip;
          beams = inferred;
          out.baseline.inferred_beams = inferred;
        }
      }
    }
  }
  // The axis fitted again on the echoes up to kFitBeyondTipMm beyond the tip. The fit's
  // cylinder runs on into the tissue ahead of the tip (the target), whose surface faces the
  // beam as an oblique catheter does not: at 50–70° to the beam it echoes as brightly as a
  // sheath that has lost its specular echo, and its voxels tilted the axis by 2–3° (the
  // independent generator's deep classes). The refit starts from the fit's echo line (the
  // cylinder around the echoes, as the fit's last pass) through the tip's point on it.
  auto echo_line_at_tip = [](const EchoAxisFit& f, const TipEstimate& t) {
    const Eigen::Vector3d d = f.echo_line.direction.dot(t.axis.direction) < 0
                                  ? Eigen::Vector3d(-f.echo_line.direction)
                                  : f.echo_line.direction;
    return Line3{f.echo_line.point + f.echo_line.Parameter(t.tip_mm) * f.echo_line.direction, d};
  };
  // Only when the fit's echoes reach on beyond the tip (a catheter imaged near normal
  // incidence outshines the tissue, whose voxels stay below the echo threshold), and kept only
  // when it turns the axis by more than kRefitMinTurnRad.
  const double s_tip = fit->axis.Parameter(tip.tip_mm);
  const double reach = fit->axis.direction.dot(tip.axis.direction) >= 0 ? fit->echo_s_max - s_tip
                                                                        : s_tip - fit->echo_s_min;
  if (auto cut = reach > kFitBeyondTipMm + kFitReachMarginMm
                     ? FitEchoAxis(v, echo_line_at_tip(*fit, tip), bg, options_.fit, beams,
                                   kFitBeyondTipMm)
                     : std::nullopt;
      cut && AngleBetweenLines(cut->axis, fit->axis) > kRefitMinTurnRad) {
    const TipEstimate retip = FindTip(v, cut->axis, bg, tip_edge);
    if (retip.found) {
      fit = std::move(cut);
      tip = retip;
    }
  }
  out.axis = tip.axis;
  out.tip_mm = tip.tip_mm;
  out.line_length_mm = tip.line_length_mm;
  const TargetEstimate target = FindTarget(v, tip, bg, options_.edge);
  out.target_found = target.found;
  out.target_mm = target.target_mm;
  out.contact = target.found && target.contact;
  out.target_gap_mm = target.gap_mm;
  out.target_indentation_mm = target.indentation_mm;
  if (target.found) {  // the tip re-located before the tissue its bright run went through
    const double shift = out.axis.Parameter(out.tip_mm) - out.axis.Parameter(target.tip_mm);
    out.tip_mm = target.tip_mm;
    out.line_length_mm = std::max(0.0, out.line_length_mm - shift);
  }

  const double s_to = out.axis.Parameter(out.tip_mm), s_from = s_to - out.line_length_mm;
  // Beams still unknown after a look over the same axis and range: what that look found.
  BeamGeometry tube_beams = beams;
  bool search_ribbon = true;
  if (!beams.known() && ribbon.looked && ribbon.s_from == s_from && ribbon.s_to == s_to) {
    if (ribbon.direction) tube_beams = BeamGeometry::Parallel(*ribbon.direction);
    search_ribbon = false;
  }
  out.tubularity = Tubularity(v, out.axis, s_from, s_to, options_.edge.dynamic_range_db,
                              options_.tube, tube_beams, search_ribbon);

  // Confidence: Radon peak contrast (robust z among the directions' best lines), length, and
  // the line's tube shape (a line within a surface is not a catheter). The peak's contrast
  // only needs to be clear (z ≥ 5): in a volume full of bright tissue the other directions'
  // best lines are bright too (a catheter beside tissue has z 9–13 where one in water has
  // 20–35), while the tube check is what tells a catheter from a line within tissue.
  // A z-score against the rest of the scene (`rest`, or a tracked frame's baseline measured so)
  // counts only for a bright run of at least twice min_line_length_mm: a catheter shows its
  // guidewire (8 mm) and some sheath, while a compact reflector is as bright from every side
  // and gains as much from leaving its own projections out (tissue cubes of 3–6 mm: runs of
  // 8–10 mm where their cross-section is dark around).
  const bool long_run = out.line_length_mm >= 2.0 * options_.min_line_length_mm;
  double c_peak = scene.scores_without_line && !long_run ? 0.0 : PeakConfidence(z_score);
  out.peak_z = z_score;
  if (rest && rest->valid && long_run && c_peak < options_.min_confidence) {
    const double z_rest = RobustZ(*rest, coarse_peak.score);
    if (PeakConfidence(z_rest) > c_peak) {
      c_peak = PeakConfidence(z_rest);
      out.peak_z = z_rest;
      // Tracking measures the catheter against the same baseline.
      out.baseline.score_median = rest->score_median;
      out.baseline.score_mad = rest->score_mad;
      out.baseline.scores_without_line = true;
    }
  }
  const double c_len = std::clamp(
      out.line_length_mm / (2.0 * std::max(1e-9, options_.min_line_length_mm)), 0.0, 1.0);
  const double c_tube = std::clamp((out.tubularity - 0.2) / 0.5, 0.0, 1.0);
  out.confidence = std::clamp(c_peak * c_len * c_tube, 0.0, 1.0);
  out.found = out.confidence >= options_.min_confidence &&
              out.line_length_mm >= options_.min_line_length_mm;
  return out;
}

}  // namespace echoservo::tracking
