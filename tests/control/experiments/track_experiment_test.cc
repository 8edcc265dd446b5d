// The seed's tip-tracking experiment (Kesner & Howe 2010, §V) on the seed-calibrated
// plant: the published figures are reproduced within ±20%, for three plant noise
// seeds, and the compensations rank as they should.
//
// Published tip MAE (mm): no compensation 1.28 (1 Hz sine) / 1.19 (mitral); iterative
// inverse 0.26 / 0.24. The ±20% band is the calibration tolerance of
// hw::SeedCalibratedPlant (its figures are a fit of a simplified model to four
// numbers, not a replay of the bench); the adaptive inverse is this project's
// addition, whose target is ≤ 0.15 mm on both trajectories.
#include "control/experiments/track_experiment.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <numbers>
#include <stdexcept>
#include <string>
#include <tuple>

#include "hw/seed_plant.h"

namespace echoservo::control {
namespace {

TrackResult RunTrack(const std::string& trajectory, const std::string& compensation,
                     std::uint64_t seed = 1) {
  TrackOptions o = TrackOptions::SeedDefaults();
  o.trajectory = trajectory;
  o.compensation = compensation;
  o.plant.seed = seed;
  return RunTrackExperiment(o);
}

// θ·gap of the seed's tracking catheter: two 90° bends, 1.6 mm sheath, 0.8 mm wire.
double GeometricWidthMm() {
  const formats::CatheterConfig c = hw::SeedTrackingCatheter();
  return c.TotalBendRad() * c.GapMm();
}

class SeedFiguresTest
    : public ::testing::TestWithParam<std::tuple<std::string, std::string, std::uint64_t>> {};

TEST_P(SeedFiguresTest, TipMaeMatchesThePublishedFigure) {
  const auto& [trajectory, compensation, seed] = GetParam();
  const TrackResult r = RunTrack(trajectory, compensation, seed);
  const bool sine = trajectory == "sine";
  EXPECT_EQ(r.limit_faults, 0u);
  EXPECT_EQ(r.records.size(), 12000u);
  EXPECT_EQ(r.tip.samples, 10000u);  // 12 s, metrics after 2 s
  if (compensation == "none") {
    const double published = sine ? 1.28 : 1.19;
    EXPECT_NEAR(r.tip.mae_mm, published, 0.2 * published);
  } else if (compensation == "iterative") {
    const double published = sine ? 0.26 : 0.24;
    EXPECT_NEAR(r.tip.mae_mm, published, 0.2 * published);
    ASSERT_EQ(r.per_run.size(), 2u);  // run 0 uncompensated, then the learned run
    EXPECT_EQ(r.per_run.back().mae_mm, r.tip.mae_mm);
    // Run 0 of the iterative method has an empty table: it is exactly the
    // uncompensated experiment.
    EXPECT_EQ(r.per_run.front().mae_mm, RunTrack(trajectory, "none", seed).tip.mae_mm);
  } else {
    EXPECT_LE(r.tip.mae_mm, 0.15);
    const double geometric = GeometricWidthMm();
    EXPECT_GE(r.width_estimate_mm, 0.8 * geometric);
    EXPECT_LE(r.width_estimate_mm, 1.2 * geometric);
  }
  EXPECT_GE(r.tip.rms_mm, r.tip.mae_mm);
  EXPECT_GE(r.tip.max_abs_mm, r.tip.rms_mm);
}

INSTANTIATE_TEST_SUITE_P(Seed, SeedFiguresTest,
                         ::testing::Combine(::testing::Values("sine", "mitral"),
                                            ::testing::Values("none", "iterative", "adaptive"),
                                            ::testing::Values(std::uint64_t{1}, std::uint64_t{17},
                                                              std::uint64_t{123})),
                         [](const ::testing::TestParamInfo<SeedFiguresTest::ParamType>& info) {
                           return std::get<0>(info.param) + "_" + std::get<1>(info.param) +
                                  "_seed" + std::to_string(std::get<2>(info.param));
                         });

TEST(TrackExperimentTest, GeometricWidthIsThetaTimesGap) {
  EXPECT_NEAR(GeometricWidthMm(), std::numbers::pi * 0.8, 1e-12);
}

TEST(TrackExperimentTest, StaticInverseBeatsNoCompensation) {
  for (const std::string trajectory : {"sine", "mitral"}) {
    const TrackResult none = RunTrack(trajectory, "none");
    const TrackResult inverse = RunTrack(trajectory, "inverse");
    EXPECT_LT(inverse.tip.mae_mm, none.tip.mae_mm) << trajectory;
    EXPECT_DOUBLE_EQ(inverse.width_estimate_mm, GeometricWidthMm());
    EXPECT_EQ(inverse.limit_faults, 0u) << trajectory;
  }
}

TEST(TrackExperimentTest, CompensationsRank) {
  for (const std::string trajectory : {"sine", "mitral"}) {
    const double none = RunTrack(trajectory, "none").tip.mae_mm;
    const double iterative = RunTrack(trajectory, "iterative").tip.mae_mm;
    const double adaptive = RunTrack(trajectory, "adaptive").tip.mae_mm;
    EXPECT_LT(iterative, 0.5 * none) << trajectory;
    EXPECT_LT(adaptive, iterative) << trajectory;
  }
}

TEST(TrackExperimentTest, MoreIterationsDoNotHurt) {
  TrackOptions o = TrackOptions::SeedDefaults();
  o.compensation = "iterative";
  o.iterations = 3;
  const TrackResult r = RunTrackExperiment(o);
  ASSERT_EQ(r.per_run.size(), 4u);
  // Each learning pass removes most of the repeatable error; what remains is noise and
  // the non-repeatable stick-slip, so later runs stay at the level of the first learned
  // one (within 20%) rather than diverging.
  for (std::size_t i = 2; i < r.per_run.size(); ++i) {
    EXPECT_LT(r.per_run[i].mae_mm, 1.2 * r.per_run[1].mae_mm) << "run " << i;
  }
  EXPECT_LT(r.per_run[1].mae_mm, 0.5 * r.per_run[0].mae_mm);
}

TEST(TrackExperimentTest, OptionsValidation) {
  auto expect_invalid = [](TrackOptions o, const std::string& needle) {
    try {
      o.Validate();
      ADD_FAILURE() << "accepted invalid " << needle;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
    EXPECT_THROW(RunTrackExperiment(o), std::invalid_argument) << needle;
  };
  EXPECT_NO_THROW(TrackOptions::SeedDefaults().Validate());
  TrackOptions o = TrackOptions::SeedDefaults();
  o.trajectory = "square";
  expect_invalid(o, "trajectory");
  o = TrackOptions::SeedDefaults();
  o.compensation = "magic";
  expect_invalid(o, "compensation");
  o = TrackOptions::SeedDefaults();
  o.duration_s = 0.0;
  expect_invalid(o, "duration");
  o = TrackOptions::SeedDefaults();
  o.metrics_start_s = o.duration_s;
  expect_invalid(o, "metrics-start");
  o = TrackOptions::SeedDefaults();
  o.iterations = 0;
  expect_invalid(o, "iterations");
  o = TrackOptions::SeedDefaults();
  o.servo.period_s = 0.0;
  expect_invalid(o, "period_s");
}

}  // namespace
}  // namespace echoservo::control
