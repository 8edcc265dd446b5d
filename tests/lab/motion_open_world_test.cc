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
  double step_mm = 0.0;          // a jump of the baseline at step_time_s
  double step_time_s = 0.0;
  double rate_swing_hz = 0.0;  // heart rate f + Δf·sin(2π t/T_r + 1)
  double rate_period_s = 12.0;
  double modulation = 0.0;  // the beat scaled by 1 + m·sin(2π t/T_m + 2)
  double modulation_period_s = 10.0;
  std::uint64_t seed = 7;
};

// Position = (1 + g·t)·(1 + m sin(2π t/T_m + 2))·Σ_k (4/k) cos(kφ + k) + drift + a·[t ≥ t0],
// φ = 2π f t − (Δf T_r)·(cos(2π t/T_r + 1) − cos 1) (rate f + Δf sin(2π t/T_r + 1)), plus
// N(0, σ²).
estimation::MotionTrace Make(const Synthetic& s) {
  std::mt19937_64 rng(s.seed);
  std::normal_distribution<double> noise(0.0, kNoiseMm);
  estimation::MotionTrace trace;
  trace.source = "synthetic";
  trace.column = "x";
  const auto n = static_cast<std::size_t>(s.duration_s * s.sample_hz);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / s.sample_hz;
    const double two_pi = 2.0 * std::numbers::pi;
    const double phase = two_pi * s.heart_hz * t -
                         s.rate_swing_hz * s.rate_period_s *
                             (std::cos(two_pi * t / s.rate_period_s + 1.0) - std::cos(1.0));
    double beat = 0.0;
    for (int k = 1; k <= s.harmonics; ++k) beat += 4.0 / k * std::cos(k * phase + k);
    beat *= 1.0 + s.modulation * std::sin(two_pi * t / s.modulation_period_s + 2.0);
    const double x = (1.0 + s.growth_per_s * t) * beat + s.slope_mm_s * t +
                     s.curvature_mm_s2 * t * t + (t >= s.step_time_s ? s.step_mm : 0.0) +
                     noise(rng);
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
  EXPECT_TRUE(d.shapes.empty());
  EXPECT_TRUE(d.formulas.empty());
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

// The proposal's fitted parameter `name` (of the file term "motion_term").
double Proposed(const MotionDiagnosis& d, const std::string& name) {
  for (const ParameterEstimate& e : d.proposal->fit.estimates)
    if (e.name == "motion_term." + name) return e.value;
  ADD_FAILURE() << "no parameter " << name << " in the proposal: " << d.summary;
  return std::nan("");
}

// The richer grammar (lab/motion_terms.h): each effect below is outside the catalog and the
// old library; discovery must name the right term, recover its ground truth and bring the
// held-out RMS to within 1.5× the noise floor.
void ExpectProposal(const MotionDiagnosis& d, const std::string& term) {
  EXPECT_EQ(d.verdict, "unexplained") << d.summary;
  ASSERT_TRUE(d.proposal.has_value()) << d.summary;
  EXPECT_NE(std::find(d.proposal->terms.begin(), d.proposal->terms.end(), term),
            d.proposal->terms.end())
      << d.summary;
  EXPECT_LE(d.proposal->rms_mm, 1.5 * d.noise_mm) << d.summary;
  EXPECT_NEAR(d.proposal->noise_ratio, d.proposal->rms_mm / d.noise_mm, 1e-12);
  ExpectContains(d.summary, "x the noise floor");
  // Learned shapes come with an unexplained verdict.
  EXPECT_FALSE(d.shapes.empty());
  // The file's defaults are the fitted values (of the selection; the refit from the file
  // lands within a fraction of a standard deviation), so that a user's refit starts there.
  const MotionTerm file = ParseMotionModel(d.proposal->spec).terms.front();
  for (std::size_t q = 0; q < file.parameters.size(); ++q) {
    for (const ParameterEstimate& e : d.proposal->fit.estimates) {
      if (e.name == "motion_term." + file.parameters[q]) {
        EXPECT_NEAR(file.start[q], e.value, 0.5 * e.sd + 1e-9) << e.name;
      }
    }
  }
}

TEST(MotionOpenWorld, AJumpIsProposedAsABaselineStep) {
  const echoservo::testing::TempDir dir("motion_open_world", true);
  Synthetic s;
  s.step_mm = 1.5;
  s.step_time_s = 17.3;
  const MotionDiagnosis d = DiagnoseMotion(ParseMotionModel("heartbeat:3"), Make(s), Options(dir));
  ExpectProposal(d, "baseline_step");
  EXPECT_NEAR(Proposed(d, "step_time_s"), s.step_time_s, 0.2) << d.summary;
  EXPECT_NEAR(Proposed(d, "step_mm"), s.step_mm, 0.1 * s.step_mm) << d.summary;
  // Its learned shape lies along time.
  ASSERT_FALSE(d.shapes.empty());
  EXPECT_EQ(d.shapes.front().where, "time_s") << d.summary;
}

TEST(MotionOpenWorld, ASwingingHeartRateIsProposedAsRateModulation) {
  const echoservo::testing::TempDir dir("motion_open_world", true);
  Synthetic s;
  s.rate_swing_hz = 6.0 / 60.0;  // ±6 bpm
  s.rate_period_s = 12.0;
  const MotionDiagnosis d = DiagnoseMotion(ParseMotionModel("heartbeat:3"), Make(s), Options(dir));
  ExpectProposal(d, "rate_modulation");
  EXPECT_NEAR(Proposed(d, "rate_period_s"), s.rate_period_s, 0.05 * s.rate_period_s) << d.summary;
  const double swing = std::hypot(Proposed(d, "rate_cos_hz"), Proposed(d, "rate_sin_hz"));
  EXPECT_NEAR(swing, s.rate_swing_hz, 0.1 * s.rate_swing_hz) << d.summary;
}

TEST(MotionOpenWorld, AModulatedBeatIsProposedAsAmplitudeModulation) {
  const echoservo::testing::TempDir dir("motion_open_world", true);
  Synthetic s;
  s.modulation = 0.25;
  s.modulation_period_s = 10.0;
  const MotionDiagnosis d = DiagnoseMotion(ParseMotionModel("heartbeat:3"), Make(s), Options(dir));
  ExpectProposal(d, "amplitude_modulation");
  EXPECT_NEAR(Proposed(d, "modulation_period_s"), s.modulation_period_s,
              0.05 * s.modulation_period_s)
      << d.summary;
  const double m = std::hypot(Proposed(d, "modulation_cos"), Proposed(d, "modulation_sin"));
  EXPECT_NEAR(m, s.modulation, 0.1 * s.modulation) << d.summary;
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
