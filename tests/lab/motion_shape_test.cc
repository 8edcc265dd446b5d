// The motion lab's richer grammar and learned shapes (lab/motion_terms.h,
// lab/motion_diagnosis.h): every library term written to an effect file gives the model it
// was fitted as; phase_rad files (and files from before it) read and fit; an unexplained
// trace gets learned shapes of its held-out residual and a Pareto front of formulas.
// Traces: the motion lab's synthetic heartbeat (control/experiments/synthetic_motion.h) and,
// for a jump, the open-world tests' form Σ_k (4/k) cos(kφ + k) + a·[t ≥ t0] + N(0, σ²).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <numbers>
#include <random>

#include "control/experiments/synthetic_motion.h"
#include "lab/motion_diagnosis.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::lab {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

constexpr double kShapeNoiseMm = 0.25;

estimation::MotionTrace ShapeTestTrace(double wander_bpm = 0.0, std::uint64_t seed = 1) {
  control::SyntheticMotionOptions o;
  o.duration_s = 30.0;
  o.sample_rate_hz = 25.0;
  o.harmonics = 3;
  o.noise_mm = kShapeNoiseMm;
  o.wander_bpm = wander_bpm;
  o.wander_tau_s = 4.0;
  o.seed = seed;
  return control::MakeSyntheticMotion(o).measured;
}

// A 1.2 Hz heartbeat with a jump of `step_mm` at `step_time_s`.
estimation::MotionTrace JumpTrace(double step_mm, double step_time_s) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, kShapeNoiseMm);
  estimation::MotionTrace trace;
  trace.source = "synthetic";
  trace.column = "x";
  for (int i = 0; i < 750; ++i) {
    const double t = i / 25.0;
    const double phase = 2.0 * std::numbers::pi * 1.2 * t;
    double x = 0.0;
    for (int k = 1; k <= 3; ++k) x += 4.0 / k * std::cos(k * phase + k);
    trace.t_s.push_back(t);
    trace.position_mm.push_back(x + (t >= step_time_s ? step_mm : 0.0) + noise(rng));
  }
  return trace;
}

// Parameter values inside the bounds that make each term matter.
std::vector<double> TermValues(const MotionTerm& t) {
  std::vector<double> v;
  for (std::size_t q = 0; q < t.parameters.size(); ++q) {
    const std::string& name = t.parameters[q];
    double x = 0.3 * t.upper[q] + 0.7 * t.lower[q];  // periods, moments, widths
    if (t.lower[q] == -t.upper[q]) x = 0.01 * t.upper[q] * (q % 2 == 0 ? 1.0 : -2.0);
    if (name.rfind("timing", 0) == 0) x = 0.3 * std::sin(static_cast<double>(q));
    v.push_back(x);
  }
  return v;
}

// The native (automatic-derivative) model and the model read back from the effect file the
// proposal writes agree at the same parameters, for every library term.
TEST(MotionTermLibrary, FilesGiveTheModelTheTermWasFittedAs) {
  const echoservo::testing::TempDir dir("motion_shape", true);
  const estimation::MotionTrace trace = ShapeTestTrace();
  const MotionModelSpec base = ParseMotionModel("heartbeat:3");
  const MotionFit fit = FitMotionModel(base, trace, kShapeNoiseMm);
  MotionTermContext context;
  context.duration_s = trace.duration_s();
  context.sample_period_s = 0.04;
  context.rate_hz = fit.parameters[1];
  const std::vector<MotionTerm> library = MotionTermLibrary(3, context);
  std::vector<std::string> names;
  for (const MotionTerm& t : library) names.push_back(t.name);
  for (const char* name : {"baseline_step", "baseline_sine", "amplitude_modulation",
                           "rate_modulation", "beat_timing"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  }
  for (MotionTerm term : library) {
    term.penalty = 0.0;
    MotionModelSpec native = base;
    native.terms.push_back(term);
    std::vector<double> p = StartMotionParameters(native, fit, trace);
    const std::vector<double> v = TermValues(term);
    std::copy(v.begin(), v.end(), p.end() - static_cast<std::ptrdiff_t>(v.size()));
    const std::string path = dir.str() + "/" + term.name + ".json";
    WriteMotionTermFile(path, "written", "test", {term});
    const MotionModelSpec from_file = ParseMotionModel("heartbeat:3+@" + path);
    ASSERT_EQ(from_file.terms.size(), 1U);
    EXPECT_EQ(from_file.terms[0].parameters, term.parameters) << term.name;
    const double a = EvaluateMotionModel(native, p, trace, kShapeNoiseMm, {});
    const double b = EvaluateMotionModel(from_file, p, trace, kShapeNoiseMm, {});
    const double none = EvaluateMotionModel(base, fit.parameters, trace, kShapeNoiseMm, {});
    EXPECT_NEAR(a, b, 1e-9 * a) << term.name;
    EXPECT_GT(std::abs(a - none), 1e-3) << term.name << ": the values must change the model";
  }
}

// A hand-written phase_rad file: a heart rate swinging ±0.1 Hz every 10 s, fitted.
TEST(MotionTermFile, PhaseTermsFitAndOldFilesStillRead) {
  const echoservo::testing::TempDir dir("motion_shape", true);
  const std::string swing = dir.str() + "/swing.json";
  std::ofstream(swing) << R"json({"format": "echoservo.effect/1", "name": "swing",
    "parameters": [{"name": "df_hz", "unit": "Hz", "default": 0.05, "lower": 0, "upper": 0.5,
                    "doc": "rate swing"}],
    "expressions": {"phase_rad": "-df_hz * 10 * cos(2 * pi * time_s / 10)"}})json";
  estimation::MotionTrace trace = ShapeTestTrace();
  // Rebuild the positions with that phase: 1.2 Hz + 0.1 Hz sin(2π t/10).
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, kShapeNoiseMm);
  for (std::size_t i = 0; i < trace.size(); ++i) {
    const double t = trace.t_s[i] - trace.t_s.front();
    const double phase =
        2.0 * std::numbers::pi * 1.2 * t - 0.1 * 10.0 * std::cos(2.0 * std::numbers::pi * t / 10.0);
    trace.position_mm[i] = 5.0 * std::cos(phase) + 2.0 * std::sin(2.0 * phase) + noise(rng);
  }
  const MotionFit fit =
      FitMotionModel(ParseMotionModel("heartbeat:2+@" + swing), trace, kShapeNoiseMm);
  std::map<std::string, ParameterEstimate> p;
  for (const ParameterEstimate& e : fit.estimates) p[e.name] = e;
  EXPECT_NEAR(p.at("swing.df_hz").value, 0.1, 4.0 * p.at("swing.df_hz").sd + 1e-4);
  EXPECT_NEAR(fit.rms_mm, kShapeNoiseMm, 0.03);
  // A file of the first format (position_mm over three inputs) reads and fits as before.
  const std::string old = dir.str() + "/old.json";
  std::ofstream(old) << R"json({"format": "echoservo.effect/1", "name": "tilt",
    "parameters": [{"name": "s_mm_s", "unit": "mm/s", "default": 0, "lower": -1, "upper": 1,
                    "doc": "slope"}],
    "expressions": {"position_mm": "s_mm_s * time_s + 0 * heart_rate_hz * cardiac_phase_rad"}})json";
  const MotionModelSpec spec = ParseMotionModel("heartbeat:2+@" + old);
  ASSERT_EQ(spec.terms.size(), 1U);
  EXPECT_TRUE(spec.terms[0].phase_expression.empty());
  EXPECT_NO_THROW(FitMotionModel(spec, ShapeTestTrace(), kShapeNoiseMm));
  // A file without either hook names both.
  const std::string none = dir.str() + "/none.json";
  std::ofstream(none) << R"json({"format": "echoservo.effect/1", "name": "push",
    "parameters": [], "expressions": {"force_n": "1"}})json";
  const std::string message =
      InvalidArgumentMessage([&] { ParseMotionModel("heartbeat:2+@" + none); });
  ExpectContains(message, none);
}

// An unexplained jump: the held-out residual learnt along time jumps by the step, and the
// Pareto front of its formulas ends with a step at the right moment.
TEST(MotionLearnedShapes, LearnAJumpAlongTimeAndDistilItIntoAStep) {
  const echoservo::testing::TempDir dir("motion_shape", true);
  MotionDiagnoseOptions o;
  o.propose_dir = dir.str();
  o.discover = false;  // the shapes alone
  const MotionDiagnosis d =
      DiagnoseMotion(ParseMotionModel("heartbeat:3"), JumpTrace(1.5, 17.3), o);
  ASSERT_EQ(d.verdict, "unexplained") << d.summary;
  EXPECT_FALSE(d.proposal.has_value());
  ASSERT_EQ(d.shapes.size(), 4U) << d.summary;
  for (std::size_t i = 1; i < d.shapes.size(); ++i)
    EXPECT_LE(d.shapes[i - 1].held_out_mse, d.shapes[i].held_out_mse);
  const LearnedMotionShape& best = d.shapes.front();
  EXPECT_EQ(best.where, "time_s");
  ASSERT_EQ(best.variables, std::vector<std::string>{"time_s"});
  // It removes most of the held-out excess (ground truth: the step's excess over the noise).
  EXPECT_GT(best.gain, 0.7 * d.excess) << d.summary;
  EXPECT_NEAR(best.shape.Evaluate(25.0) - best.shape.Evaluate(10.0), 1.5, 0.15);
  ExpectContains(d.summary, "learned shape along time_s");
  ASSERT_FALSE(d.formulas.empty());
  for (std::size_t i = 1; i < d.formulas.size(); ++i) {
    EXPECT_GT(d.formulas[i].complexity, d.formulas[i - 1].complexity);
    EXPECT_LT(d.formulas[i].held_out_mse, d.formulas[i - 1].held_out_mse);
  }
  const auto step = std::find_if(d.formulas.begin(), d.formulas.end(),
                                 [](const Formula& f) { return f.form == "step"; });
  ASSERT_NE(step, d.formulas.end()) << d.summary;
  for (const FormulaConstant& c : step->constants) {
    if (c.name == "x0") {
      EXPECT_NEAR(c.value, 17.3, 0.3);
    }
    if (c.name == "amplitude") {
      EXPECT_NEAR(c.value, 1.5, 0.15);
    }
  }
}

// Beat-to-beat timing changes (the synthetic heartbeat's Ornstein–Uhlenbeck rate wander,
// ±2 bpm, 4 s): beat_timing is proposed. A wander cannot be predicted into a held-out time
// block, so the held-out RMS stays above the noise, but most of the excess goes, and the
// in-sample fit reaches the noise (ground truth 0.25 mm).
TEST(MotionOpenWorld, BeatToBeatTimingChangesAreProposedAsBeatTiming) {
  const echoservo::testing::TempDir dir("motion_shape", true);
  MotionDiagnoseOptions o;
  o.propose_dir = dir.str();
  const MotionDiagnosis d = DiagnoseMotion(ParseMotionModel("heartbeat:3"), ShapeTestTrace(2.0), o);
  ASSERT_EQ(d.verdict, "unexplained") << d.summary;
  ASSERT_TRUE(d.proposal.has_value()) << d.summary;
  EXPECT_EQ(d.proposal->terms.front(), "beat_timing") << d.summary;
  EXPECT_LT(d.proposal->cv_mse - 1.0, 0.1 * d.excess) << d.summary;
  EXPECT_NEAR(d.proposal->fit.rms_mm, kShapeNoiseMm, 0.15 * kShapeNoiseMm) << d.summary;
  // The file holds the knots as a phase_rad hook.
  EXPECT_FALSE(ParseMotionModel(d.proposal->spec).terms.front().phase_expression.empty());
}

}  // namespace
}  // namespace echoservo::lab
