#include "tracking/exhaustive_radon.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "tracking/radon_transform.h"

namespace echoservo::tracking {
namespace {

// Indices of up to k best directions, each at least `sep` rad from the ones before.
std::vector<std::size_t> DistinctBest(const std::vector<Eigen::Vector3d>& dirs,
                                      const std::vector<double>& scores, int k, double sep) {
  std::vector<std::size_t> order(scores.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return scores[a] > scores[b]; });
  std::vector<std::size_t> out;
  for (auto i : order) {
    if (static_cast<int>(out.size()) >= k || !(scores[i] > 0)) break;
    bool far = true;
    for (auto j : out)
      if (std::acos(std::min(1.0, std::abs(dirs[i].normalized().dot(dirs[j].normalized())))) < sep)
        far = false;
    if (far) out.push_back(i);
  }
  return out;
}

struct Best {
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  double score = -1;
};

void Keep(const RadonSearchResult& r, Best& best) {
  if (r.peak.score > best.score) {
    best.score = r.peak.score;
    best.direction = r.direction;
  }
}

}  // namespace

void ExhaustiveRadonOptions::Validate() const {
  auto bad = [](const char* f) {
    std::string m = "ExhaustiveRadonOptions: bad ";
    m += f;
    throw std::invalid_argument(m);
  };
  if (hemisphere_directions < 16 || hemisphere_directions > 1000000) bad("hemisphere_directions");
  if (refine_candidates < 1 || refine_candidates > 100) bad("refine_candidates");
  if (!(candidate_separation_rad > 0 && candidate_separation_rad < 1.6))
    bad("candidate_separation_rad");
  if (!(cone_half_rad > 0 && cone_half_rad <= 0.5)) bad("cone_half_rad");
  if (cone_steps < 2 || cone_steps > 201) bad("cone_steps");
  if (!(fine_half_rad > 0 && fine_half_rad <= 0.5)) bad("fine_half_rad");
  if (fine_steps < 2 || fine_steps > 201) bad("fine_steps");
  if (!(max_depth_fraction > 0 && max_depth_fraction <= 1)) bad("max_depth_fraction");
  if (!(parallel_peak_ratio > 0 && parallel_peak_ratio <= 1)) bad("parallel_peak_ratio");
  if (!(parallel_max_shallower_mm >= 0 && std::isfinite(parallel_max_shallower_mm)))
    bad("parallel_max_shallower_mm");
}

ExhaustiveRadonResult ExhaustiveRadonAxis(const imaging::Volume& v,
                                          const ExhaustiveRadonOptions& o) {
  o.Validate();
  ExhaustiveRadonResult out;
  if (v.dims().minCoeff() < 8) return out;
  const RadonLevel level = MakeRadonLevel(v, 1, o.max_depth_fraction);
  out.bin_mm = level.bin_mm;
  if (level.cells.empty()) return out;

  const auto hemi = FibonacciHemisphere(o.hemisphere_directions);
  const RadonSearchResult coarse = SearchDirections(level, hemi, nullptr);
  out.directions += static_cast<int>(hemi.size());
  Best best;
  Keep(coarse, best);
  for (auto i :
       DistinctBest(hemi, coarse.scores, o.refine_candidates, o.candidate_separation_rad)) {
    const auto cone = DirectionCone(hemi[i], o.cone_half_rad, o.cone_steps);
    Keep(SearchDirections(level, cone, nullptr), best);
    out.directions += static_cast<int>(cone.size());
  }
  const auto fine = DirectionCone(best.direction, o.fine_half_rad, o.fine_steps);
  Keep(SearchDirections(level, fine, nullptr), best);
  out.directions += static_cast<int>(fine.size());
  if (!(best.score > 0)) return out;

  // Parallel near-equal peaks (reverberation): the shallowest within the allowed depth.
  const auto peaks = RadonPeaks(level, best.direction, nullptr, false);
  if (peaks.empty()) return out;
  const Line3 top = PeakLine(level, best.direction, peaks.front());
  Line3 chosen = top;
  double chosen_score = peaks.front().score;
  for (const auto& p : peaks) {
    if (p.score < o.parallel_peak_ratio * peaks.front().score) break;
    const Line3 l = PeakLine(level, best.direction, p);
    if (l.point.z() < chosen.point.z() &&
        top.point.z() - l.point.z() <= o.parallel_max_shallower_mm) {
      chosen = l;
      chosen_score = p.score;
    }
  }
  out.found = true;
  out.axis = chosen;
  out.score = chosen_score;
  return out;
}

AxisAgreement CompareAxes(const Line3& detected, const Eigen::Vector3d& point_mm,
                          const Line3& reference) {
  AxisAgreement a;
  a.angle_deg = AngleBetweenLines(detected, reference) * 180.0 / std::numbers::pi;
  a.offset_mm = PointToLineDistance(reference, point_mm);
  return a;
}

}  // namespace echoservo::tracking
