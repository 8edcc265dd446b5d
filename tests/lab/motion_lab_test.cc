// The motion lab: on synthetic traces with one hidden effect, `DiagnoseMotion` names it;
// with none, the model is adequate. Also the baselines and the model SPEC parser.
#include <gtest/gtest.h>

#include "control/experiments/synthetic_motion.h"
#include "estimation/motion_predictor.h"
#include "lab/candidate_ranking.h"
#include "lab/motion_diagnosis.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/sanitizers.h"

namespace echoservo::lab {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;

estimation::MotionTrace Trace(int harmonics, double respiration_mm, double drift_bpm_per_min) {
  control::SyntheticMotionOptions o;
  o.duration_s = 30.0;
  o.sample_rate_hz = 25.0;
  o.harmonics = harmonics;
  o.respiration_mm = respiration_mm;
  o.rate_drift_bpm_per_min = drift_bpm_per_min;
  o.noise_mm = 0.3;
  return control::MakeSyntheticMotion(o).measured;
}

struct Hidden {
  const char* name;
  const char* model;
  int harmonics;
  double respiration_mm;
  double drift;
  const char* expected;  // "" = adequate
};

class MotionDiagnose : public ::testing::TestWithParam<Hidden> {};

TEST_P(MotionDiagnose, NamesTheHiddenEffect) {
  const Hidden h = GetParam();
  // Every case takes the same path (fits of the same candidates); under the sanitizers, where
  // each takes 3-5 s, the respiration case runs for all four.
  if (std::string(h.name) != "respiration")
    ECHOSERVO_RELEASE_SUITE_ONLY("the respiration case takes the same diagnosis path");
  const estimation::MotionTrace trace = Trace(h.harmonics, h.respiration_mm, h.drift);
  const MotionDiagnosis d = DiagnoseMotion(ParseMotionModel(h.model), trace);
  EXPECT_NEAR(d.noise_mm, 0.3, 0.05);  // the synthetic noise σ
  if (std::string(h.expected).empty()) {
    EXPECT_TRUE(d.adequate) << d.summary;
    EXPECT_EQ(d.verdict, "adequate");
    EXPECT_NEAR(d.base.rms_mm, 0.3, 0.05);
    return;
  }
  ASSERT_FALSE(d.adequate) << d.summary;
  EXPECT_EQ(d.verdict, "missing_effect") << d.summary;
  EXPECT_EQ(d.candidates.front().effect, h.expected) << d.summary;
  // The winner brings the residual down to the noise; the others are not significant.
  EXPECT_NEAR(d.candidates.front().fit.rms_mm, 0.3, 0.05);
  for (std::size_t i = 1; i < d.candidates.size(); ++i) EXPECT_FALSE(d.candidates[i].significant);
  ExpectContains(d.summary, std::string("missing effect: ") + h.expected);
}

INSTANTIATE_TEST_SUITE_P(
    Traces, MotionDiagnose,
    ::testing::Values(Hidden{"respiration", "heartbeat:6", 6, 2.0, 0.0, "respiration"},
                      Hidden{"rate_drift", "heartbeat:6", 6, 0.0, 20.0, "rate_drift"},
                      Hidden{"harmonics", "heartbeat:2", 3, 0.0, 0.0, "harmonic"},
                      Hidden{"none", "heartbeat:3", 3, 0.0, 0.0, ""}),
    [](const auto& info) { return std::string(info.param.name); });

TEST(MotionModel, SpecsParseAndBadOnesNameTheCatalog) {
  const MotionModelSpec s = ParseMotionModel("heartbeat:3+respiration+harmonic");
  EXPECT_EQ(s.harmonics, 4);
  EXPECT_TRUE(s.respiration);
  EXPECT_FALSE(s.rate_drift);
  EXPECT_EQ(FormatMotionModel(s), "heartbeat:4+respiration");
  ExpectContains(InvalidArgumentMessage([] { ParseMotionModel("heartbeat:3+wobble"); }),
                 "unknown term 'wobble'");
  ExpectContains(InvalidArgumentMessage([] { ParseMotionModel("fourier:3"); }), "heartbeat:N");
  ExpectContains(InvalidArgumentMessage([] { ParseMotionModel("heartbeat:0"); }),
                 "bad harmonic count");
}

TEST(CandidateRanking, JudgesByTheHeldOutExcess) {
  const SignificanceRule rule;
  const Judgement a = JudgeCandidate({3.0}, {1.2}, rule);  // removes 90 % of an excess of 2
  EXPECT_TRUE(a.significant);
  EXPECT_NEAR(a.explained[0], 0.9, 1e-12);
  const Judgement b = JudgeCandidate({1.2}, {1.0}, rule);  // excess below 0.5: nothing to explain
  EXPECT_FALSE(b.significant);
  EXPECT_TRUE(std::isnan(b.explained[0]));
  const Judgement c =
      JudgeCandidate({3.0, 3.0}, {1.0, 5.0}, rule);  // helps one channel, hurts the other
  EXPECT_FALSE(c.significant);
}

TEST(Baselines, AreExactOnTheMotionTheyAssume) {
  estimation::ZeroOrderHold zoh;
  estimation::LinearExtrapolation lin;
  estimation::ConstantVelocityKf kf({1.0, 0.01});
  for (int i = 0; i <= 100; ++i) {
    const double t = 0.04 * i;
    zoh.Update(t, 3.0 + 5.0 * t);
    lin.Update(t, 3.0 + 5.0 * t);
    kf.Update(t, 3.0 + 5.0 * t);
  }
  EXPECT_DOUBLE_EQ(zoh.Predict(4.1), 23.0);
  EXPECT_NEAR(lin.Predict(4.1), 23.5, 1e-9);
  EXPECT_NEAR(kf.Predict(4.1), 23.5, 1e-3);
  ExpectContains(InvalidArgumentMessage([] {
                   estimation::ConstantVelocityKf({0.0, 1.0});
                 }),
                 "q and the noise");
}

}  // namespace
}  // namespace echoservo::lab
