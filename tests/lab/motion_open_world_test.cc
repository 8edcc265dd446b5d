// The motion lab in an open world: effects outside the motion catalog. On synthetic traces
// made here (a constant-rate heartbeat plus white noise σ = 0.25 mm, plus one effect):
// the noise floor does not grow with the effect, the null trace is adequate, an amplitude
// growth and a baseline drift are unexplained with the right `where`, and the proposed term
// brings the held-out RMS down to the noise; file-defined terms fit and bad ones name the
// file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <random>

#include "hw/effect_file.h"
#include "lab/motion_diagnosis.h"
#include "lab/motion_noise.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::lab {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

constexpr double kNoiseMm = 0.25;

struct Synthetic {
  double duration_s = 30.0;
  double sample_hz = 25.0;
  double heart_hz = 1.2;
  int harmonics = 3;
  double growth_per_s = 0.0;     // relative amplitude growth of the beat, 1/s
  double slope_mm_s = 0.0;       // baseline drift
  double curvature_mm_s2 = 0.0;  // baseline bend
  std::uint64_t seed = 7;
};

// Position = (1 + g·t)·Σ_k (4/k) cos(kφ + k) + drift, φ = 2π f t, plus N(0, σ²).
estimation::MotionTrace Make(const Synthetic& s) {
  std::mt19937_64 rng(s.seed);
  std::normal_distribution<double> noise(0.0, kNoiseMm);
  estimation::MotionTrace trace;
  trace.source = "synthetic";
  trace.column = "x";
  const auto n = static_cast<std::size_t>(s.duration_s * s.sample_hz);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / s.sample_hz;
    const double phase = 2.0 * std::numbers::pi * s.heart_hz * t;
    double beat = 0.0;
    for (int k = 1; k <= s.harmonics; ++k) beat += 4.0 / k * std::cos(k * phase + k);
    const double x = (1.0 + s.growth_per_s * t) * beat + s.slope_mm_s * t +
                     s.curvature_mm_s2 * t * t + noise(rng);
    trace.t_s.push_back(t);
    trace.position_mm.push_back(x);
  }
  return trace;
}

Synthetic Growth() {
  Synthetic s;
  s.growth_per_s = 0.5 / 30.0;  // the beat grows by half over the trace
  return s;
}

Synthetic Drift() {
  Synthetic s;
  s.slope_mm_s = 0.05;
  s.curvature_mm_s2 = 0.004;  // 1.5 + 3.6 mm over 30 s
  return s;
}

TEST(MotionNoise, StaysAtTheNoiseWhatEverSlowEffectIsAdded) {
  const double null = EstimateMotionNoise(Make(Synthetic{})).position_mm;
  EXPECT_NEAR(null, kNoiseMm, 0.2 * kNoiseMm);
  for (const Synthetic& s : {Growth(), Drift()}) {
    const double with = EstimateMotionNoise(Make(s)).position_mm;
    EXPECT_NEAR(with, kNoiseMm, 0.2 * kNoiseMm);
    EXPECT_LE(with, 1.1 * null);  // same noise draw: the effect must not raise it
  }
}

// Heart rates 36-222 bpm at 25 and 30 Hz, 4 harmonics with 1/k amplitudes (12 mm peak to
// peak): the heartbeat itself must not pass for noise.
TEST(MotionNoise, IsNotInflatedByTheHeartbeatAtLowSamplingRates) {
  for (double fs : {25.0, 30.0}) {
    for (double f : {0.6, 1.2, 2.4, 3.7}) {
      Synthetic s;
      s.sample_hz = fs;
      s.heart_hz = f;
      s.harmonics = 4;
      s.duration_s = 20.0;
      const MotionNoise n = EstimateMotionNoise(Make(s));
      EXPECT_NEAR(n.position_mm, kNoiseMm, 0.2 * kNoiseMm)
          << fs << " Hz sampling, " << f << " Hz heart rate: differences " << n.difference_mm
          << " mm (order " << n.difference_order << "), local fits " << n.local_fit_mm << " mm";
    }
  }
}

MotionDiagnoseOptions Options(const echoservo::testing::TempDir& dir) {
  MotionDiagnoseOptions o;
  o.propose_dir = dir.str();
  return o;
}

TEST(MotionOpenWorld, NullTraceIsAdequateWithoutStructure) {
  const echoservo::testing::TempDir dir("motion_open_world", true);
  const MotionDiagnosis d =
      DiagnoseMotion(ParseMotionModel("heartbeat:3"), Make(Synthetic{}), Options(dir));
  EXPECT_EQ(d.verdict, "adequate") << d.summary;
  EXPECT_TRUE(d.adequate);
  EXPECT_LT(d.excess, 0.5);
  EXPECT_FALSE(d.proposal.has_value());
  ASSERT_EQ(d.where.size(), 4U);
  for (const WhereEntry& e : d.where) {
    EXPECT_LT(e.gain, 0.25) << e.variable;  // the significance threshold
    EXPECT_LT(e.gain, 0.05) << e.variable;  // noise alone: about 0 or below
  }
}

void ExpectUnexplained(const MotionDiagnosis& d, const std::string& first_where,
                       const std::string& term) {
  EXPECT_EQ(d.verdict, "unexplained") << d.summary;
  EXPECT_FALSE(d.adequate);
  EXPECT_GT(d.excess, 0.5);
  for (const MotionCandidate& c : d.candidates) EXPECT_FALSE(c.significant) << c.effect;
  ASSERT_FALSE(d.where.empty());
  EXPECT_EQ(d.where.front().variable, first_where) << d.summary;
  EXPECT_GE(d.where.front().gain, 0.25);
  ExpectContains(d.summary, "lies along " + first_where);
  ASSERT_TRUE(d.proposal.has_value()) << d.summary;
  EXPECT_LE(d.proposal->rms_mm, 1.5 * d.noise_mm) << d.summary;
  EXPECT_LT(d.proposal->rms_mm, 0.5 * d.held_out_rms_mm);
  EXPECT_NE(std::find(d.proposal->terms.begin(), d.proposal->terms.end(), term),
            d.proposal->terms.end())
      << d.summary;
  EXPECT_TRUE(std::filesystem::exists(d.proposal->file));
  ExpectContains(d.proposal->spec, "heartbeat:3+@" + d.proposal->file);
  // The SPEC a user would type gives the same model.
  const MotionModelSpec again = ParseMotionModel(d.proposal->spec);
  ASSERT_EQ(again.terms.size(), 1U);
  EXPECT_EQ(again.terms.front().kind, MotionTermKind::kFile);
}

TEST(MotionOpenWorld, AmplitudeGrowthIsUnexplainedAlongPhaseAndTime) {
  const echoservo::testing::TempDir dir("motion_open_world", true);
  const MotionDiagnosis d =
      DiagnoseMotion(ParseMotionModel("heartbeat:3"), Make(Growth()), Options(dir));
  ExpectUnexplained(d, "cardiac_phase_x_time", "amplitude_growth1");
}

TEST(MotionOpenWorld, BaselineDriftIsUnexplainedAlongTime) {
  const echoservo::testing::TempDir dir("motion_open_world", true);
  const MotionDiagnosis d =
      DiagnoseMotion(ParseMotionModel("heartbeat:3"), Make(Drift()), Options(dir));
  ExpectUnexplained(d, "time_s", "baseline_quadratic");
}

// A hand-written term file: the drift's slope and curvature come back from a 60 s trace at
// 30 Hz fitted with the file term's numeric derivatives.
TEST(MotionTermFile, FitsWithTheHeartbeat) {
  const echoservo::testing::TempDir dir("motion_open_world", true);
  const std::string path = dir.str() + "/drift.json";
  hw::EffectFileSpec spec;
  spec.name = "drift";
  spec.description = "a quadratic baseline";
  spec.parameters = {{"a_mm_s", "mm/s", 0.0, -10.0, 10.0, "slope"},
                     {"c_mm_s2", "mm/s^2", 0.0, -1.0, 1.0, "curvature"}};
  spec.expressions = {{"position_mm", "a_mm_s*time_s + c_mm_s2*time_s^2"}};
  hw::WriteEffectFile(path, spec);
  Synthetic s = Drift();
  s.duration_s = 60.0;
  s.sample_hz = 30.0;
  const estimation::MotionTrace trace = Make(s);
  const MotionModelSpec model = ParseMotionModel("heartbeat:3+@" + path);
  EXPECT_EQ(FormatMotionModel(model), "heartbeat:3+@" + path);
  const MotionFit fit = FitMotionModel(model, trace, kNoiseMm);
  EXPECT_NEAR(fit.rms_mm, kNoiseMm, 0.03);
  std::map<std::string, ParameterEstimate> p;
  for (const ParameterEstimate& e : fit.estimates) p[e.name] = e;
  // Tolerances: 4 standard deviations of the fit.
  EXPECT_NEAR(p.at("drift.a_mm_s").value, s.slope_mm_s, 4.0 * p.at("drift.a_mm_s").sd);
  EXPECT_NEAR(p.at("drift.c_mm_s2").value, s.curvature_mm_s2, 4.0 * p.at("drift.c_mm_s2").sd);
  EXPECT_NEAR(p.at("heart_rate").value, s.heart_hz, 1e-3);
}

TEST(MotionTermFile, BadFilesNameTheFileAndWhy) {
  const echoservo::testing::TempDir dir("motion_open_world", true);
  const std::string missing = dir.str() + "/missing.json";
  ExpectContains(InvalidArgumentMessage([&] { ParseMotionModel("heartbeat:2+@" + missing); }),
                 missing);
  const std::string bad = dir.str() + "/bad.json";
  std::ofstream(bad) << R"json({"format": "echoservo.effect/1", "name": "wobble",
    "parameters": [{"name": "a_mm", "unit": "mm", "default": 0, "lower": -1, "upper": 1,
                    "doc": "amplitude"}],
    "expressions": {"position_mm": "a_mm * sin(beat_phase)"}})json";
  const std::string message =
      InvalidArgumentMessage([&] { ParseMotionModel("heartbeat:2+@" + bad); });
  ExpectContains(message, bad);
  ExpectContains(message, "expressions.position_mm");
  ExpectContains(message, "beat_phase");
  const std::string catheter = dir.str() + "/catheter.json";
  std::ofstream(catheter) << R"json({"format": "echoservo.effect/1", "name": "push",
    "parameters": [], "expressions": {"force_n": "1"}})json";
  const std::string hook =
      InvalidArgumentMessage([&] { ParseMotionModel("heartbeat:2+@" + catheter); });
  ExpectContains(hook, catheter);
  ExpectContains(hook, "force_n");
}

}  // namespace
}  // namespace echoservo::lab
