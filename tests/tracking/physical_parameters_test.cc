// The detector's physical parameters (the sheath's and the guidewire's outer diameters) are
// physical: on volumes made with a known value, a study over a grid of settings finds that
// value best within one grid step, and no other setting beats it by more than the noise floor
// (issue 32, item 4; the display's dynamic range does not pass yet: docs/detector.md). The
// simulated scanner at a 30°×14°×70 mm field of view: the sheath shows ~7 mm before its end, below
// min_sheath_span_mm (10), so the guidewire's echoes join the axis fit and its diameter matters
// too. A few volumes each.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "imaging/sim/simulated_scanner.h"
#include "tests/test_util/constants.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/sanitizers.h"
#include "tracking/radon_detector.h"

namespace echoservo::tracking {
namespace {

using imaging::sim::SimulatedScanner;
using imaging::sim::SimulatedScannerOptions;
using testing::ExpectContains;
using testing::InvalidArgumentMessage;
using testing::kDeg;

// `echoservo scanner --fov 30,14,70`: the default beam and voxel density over a smaller field.
void SmallFieldOfView(imaging::sim::ProbeGeometry& p) {
  const imaging::sim::ProbeGeometry d;
  const double az = 30 * kDeg, el = 14 * kDeg, range = 70;
  const double fa = std::sin(0.5 * az) / std::sin(0.5 * d.azimuth_rad);
  const double fe = std::sin(0.5 * el) / std::sin(0.5 * d.elevation_rad);
  const double fr = range / d.range_mm;
  auto scaled = [](int n, double f) { return std::max(8, static_cast<int>(std::lround(n * f))); };
  p.azimuth_rad = az;
  p.elevation_rad = el;
  p.range_mm = range;
  p.n_azimuth = scaled(d.n_azimuth, az / d.azimuth_rad);
  p.n_elevation = scaled(d.n_elevation, el / d.elevation_rad);
  p.n_samples = scaled(d.n_samples, fr);
  p.volume_dims =
      Eigen::Vector3i(scaled(d.volume_dims.x(), fa * fr), scaled(d.volume_dims.y(), fe * fr),
                      scaled(d.volume_dims.z(), fr));
}

struct Frame {
  imaging::Volume volume;
  imaging::FrameGroundTruth truth;
};

std::vector<Frame> Record(const std::function<void(SimulatedScannerOptions&)>& as_built,
                          int frames = 3) {
  SimulatedScannerOptions o;
  SmallFieldOfView(o.probe);
  as_built(o);
  std::vector<Frame> out;
  for (int seed = 1; seed <= frames; ++seed) {
    o.seed = static_cast<std::uint64_t>(seed);
    SimulatedScanner scanner(o);
    auto f = scanner.Next();
    EXPECT_TRUE(f && f->truth && f->truth->catheter_visible);
    out.push_back({std::move(f->volume), *f->truth});
  }
  return out;
}

// RMS over the frames of the axis angle (deg), the tip and the target error (mm); a frame
// not found counts 10° / 10 mm.
struct Score {
  double axis_deg = 0, tip_mm = 0, target_mm = 0;
};

Score Study(const std::vector<Frame>& frames, const RadonDetectorOptions& o) {
  const RadonDetector detector(o);
  Score s;
  for (const auto& f : frames) {
    const auto d = detector.Detect(f.volume);
    const bool ok = d.found && d.target_found;
    const double a =
        ok ? AngleBetweenLines(d.axis, Line3{f.truth.axis_point_mm, f.truth.axis_direction}) / kDeg
           : 10;
    const double t = ok ? (d.tip_mm - f.truth.tip_mm).norm() : 10;
    const double g = ok ? (d.target_mm - f.truth.target_mm).norm() : 10;
    s.axis_deg += a * a;
    s.tip_mm += t * t;
    s.target_mm += g * g;
  }
  const double n = static_cast<double>(frames.size());
  s.axis_deg = std::sqrt(s.axis_deg / n);
  s.tip_mm = std::sqrt(s.tip_mm / n);
  s.target_mm = std::sqrt(s.target_mm / n);
  return s;
}

// The study's verdict: the grid value with the least combined error (tip + target + the
// axis's lateral error 10 mm from the tip, 0.17 mm per degree) lies within one grid step of
// `truth`; and per metric, the error at `truth` is within the metric's noise floor of the
// grid's least (a metric the parameter does not move ties everywhere).
void ExpectTrueValueBest(const std::string& name, const std::vector<Frame>& frames, double truth,
                         const std::vector<double>& grid,
                         const std::function<void(RadonDetectorOptions&, double)>& set) {
  std::vector<Score> scores;
  for (double v : grid) {
    RadonDetectorOptions o;
    set(o, v);
    scores.push_back(Study(frames, o));
    std::printf("%s = %.2f (as built %.2f): axis %.3f deg, tip %.3f mm, target %.3f mm\n",
                name.c_str(), v, truth, scores.back().axis_deg, scores.back().tip_mm,
                scores.back().target_mm);
  }
  std::size_t at_truth = grid.size();
  for (std::size_t i = 0; i < grid.size(); ++i)
    if (std::abs(grid[i] - truth) < 1e-9) at_truth = i;
  ASSERT_LT(at_truth, grid.size()) << "the grid must hold the value as built";
  const double step =
      std::max(at_truth > 0 ? grid[at_truth] - grid[at_truth - 1] : 0.0,
               at_truth + 1 < grid.size() ? grid[at_truth + 1] - grid[at_truth] : 0.0);
  auto combined = [](const Score& s) { return s.tip_mm + s.target_mm + 0.17 * s.axis_deg; };
  std::size_t best = 0;
  for (std::size_t i = 1; i < grid.size(); ++i)
    if (combined(scores[i]) < combined(scores[best])) best = i;
  EXPECT_LE(std::abs(grid[best] - truth), step + 1e-9)
      << name << ": the study's best is " << grid[best] << ", as built " << truth;
  const struct {
    const char* metric;
    double Score::*field;
    double floor;
  } metrics[] = {{"axis", &Score::axis_deg, 0.1},
                 {"tip", &Score::tip_mm, 0.05},
                 {"target", &Score::target_mm, 0.05}};
  for (const auto& m : metrics) {
    double least = std::numeric_limits<double>::infinity();
    for (const Score& s : scores) least = std::min(least, s.*m.field);
    EXPECT_LE(scores[at_truth].*m.field, least + m.floor)
        << name << " " << m.metric << ": " << scores[at_truth].*m.field << " as built (" << truth
        << ") against " << least << " at best";
  }
}

TEST(PhysicalParameters, TheSheathDiameterAsBuiltIsBest) {
  ECHOSERVO_RELEASE_SUITE_ONLY("a study: 2 sheaths × 5 settings × 3 volumes");
  for (double d : {1.6, 2.5}) {
    const auto frames =
        Record([&](SimulatedScannerOptions& o) { o.catheter_geometry.sheath_diameter_mm = d; });
    ExpectTrueValueBest("detector.sheath_diameter_mm", frames, d,
                        {d - 0.6, d - 0.3, d, d + 0.3, d + 0.6},
                        [](RadonDetectorOptions& o, double v) { o.fit.sheath_diameter_mm = v; });
  }
}

TEST(PhysicalParameters, TheWireDiameterAsBuiltIsBest) {
  ECHOSERVO_RELEASE_SUITE_ONLY("a study: 2 guidewires × 5 settings × 3 volumes");
  for (double w : {0.9, 1.3}) {
    const auto frames =
        Record([&](SimulatedScannerOptions& o) { o.catheter_geometry.wire_diameter_mm = w; });
    ExpectTrueValueBest("detector.wire_diameter_mm", frames, w,
                        {w - 0.4, w - 0.2, w, w + 0.2, w + 0.4},
                        [](RadonDetectorOptions& o, double v) { o.fit.wire_diameter_mm = v; });
  }
}

// A catheter the near-wall model cannot describe is refused, naming the setting and why.
TEST(PhysicalParameters, ACatheterTheModelCannotDescribeIsRefused) {
  EchoAxisFitOptions o;
  o.wire_diameter_mm = o.sheath_diameter_mm;  // no lumen left for the wire
  std::string why = InvalidArgumentMessage([&] { o.Validate(); });
  ExpectContains(why, "wire_diameter_mm");
  ExpectContains(why, "lumen");
  o = {};
  o.sheath_diameter_mm = 6;  // wider than the fit's cylinder (2 × 2.5 mm)
  why = InvalidArgumentMessage([&] { o.Validate(); });
  ExpectContains(why, "sheath_diameter_mm = 6");
  ExpectContains(why, "fit_radius_mm");
  o.fit_radius_mm = 3;  // a fit wide enough: modelled
  EXPECT_NO_THROW(o.Validate());
  o = {};
  o.sheath_diameter_mm = 0;  // no near-wall model, but a guidewire offset
  ExpectContains(InvalidArgumentMessage([&] { o.Validate(); }), "wire_diameter_mm");
  RadonDetectorOptions d;
  d.fit.sheath_diameter_mm = 7;
  ExpectContains(InvalidArgumentMessage([&] { RadonDetector{d}; }), "sheath_diameter_mm");
}

}  // namespace
}  // namespace echoservo::tracking
