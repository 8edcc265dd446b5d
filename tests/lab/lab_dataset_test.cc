// The model lab's dataset preparation (lab/lab_dataset.h): the robust noise
// estimate, the base velocity, the fit samples, the "may stick" mask, and loading a
// folder of trials with and without skipping bad files.
//
// Tolerances:
//  - EstimateNoise is 1.4826·MAD(second differences)/√6. For n Gaussian second
//    differences the MAD's relative standard error is ≈ 1.17/√n (asymptotic efficiency of
//    the MAD, 37%); with n ≈ 20 000 that is ≈ 0.8 %, and the second differences of
//    neighbouring samples are correlated (lag-1 correlation −2/3), which roughly doubles
//    it. 10 % is > 5 standard errors. The smooth signal's own second difference
//    (A·ω²·dt² ≈ 5e-5 mm) is < 0.2 % of σ.
//  - The centred difference of a straight line is exact up to roundoff: the ramp is
//    0.5 + 12.5·t with t = i·1e-3, so each value carries ≈ 1e-15 mm of rounding and a
//    difference over ≥ 5 ms divides it by ≥ 5e-3 s: ~1e-12 mm/s. We allow 1e-9.
#include "lab/lab_dataset.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "formats/trial_io.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"
#include "tests/test_util/trial_files.h"

namespace echoservo::lab {
namespace {

namespace fs = std::filesystem;
using echoservo::testing::BadCell;
using echoservo::testing::BadTrial;
using echoservo::testing::ExpectContains;
using echoservo::testing::MalformedJsonSidecar;
using echoservo::testing::MissingJsonSidecar;
using echoservo::testing::MissingLastColumn;
using echoservo::testing::TempDir;

formats::CatheterConfig Config() {
  formats::CatheterConfig c;
  c.sheath_id_mm = 2.38;
  c.guidewire_od_mm = 1.50;
  c.bends = {{90.0, 50.0}, {90.0, 25.0}};
  c.tip_load_n = 0.5;
  return c;
}

// A trial sampled at 1 kHz whose base follows `base(t)`; tip and force are smooth.
formats::Trial MakeTrial(const std::string& name, std::size_t n,
                         const std::function<double(double)>& base) {
  formats::Trial t;
  t.name = name;
  t.config = Config();
  for (std::size_t i = 0; i < n; ++i) {
    const double ts = static_cast<double>(i) * 1e-3;
    t.t_s.push_back(ts);
    t.base_cmd_mm.push_back(base(ts));
    t.base_mm.push_back(base(ts));
    t.tip_mm.push_back(base(ts) - 0.4);
    t.force_n.push_back(0.5 * std::sin(3.0 * ts));
  }
  return t;
}

// ------------------------------------------------------------------ EstimateNoise

TEST(EstimateNoise, RecoversWhiteNoiseOnASmoothSignalWithinTenPercent) {
  std::mt19937_64 rng(42);
  for (double sigma : {0.003, 0.03, 0.3}) {
    std::normal_distribution<double> normal(0.0, sigma);
    std::vector<double> x;
    for (int i = 0; i < 20000; ++i) {
      const double t = i * 1e-3;
      x.push_back(5.0 * std::sin(2.0 * std::numbers::pi * 0.5 * t) + normal(rng));
    }
    EXPECT_NEAR(EstimateNoise(x, 0.0), sigma, 0.1 * sigma) << "sigma " << sigma;
  }
}

TEST(EstimateNoise, IsFlooredByTheQuantumAndTheFloor) {
  // A slow ramp read through a 0.0125 mm quantiser: almost every second difference is 0,
  // so the MAD is 0 and only the quantisation noise q/√12 remains.
  const double q = 0.0125;
  std::vector<double> x;
  for (int i = 0; i < 5000; ++i) x.push_back(q * std::round(0.5 * i * 1e-3 / q));
  EXPECT_NEAR(EstimateNoise(x, 0.0), q / std::sqrt(12.0), 1e-15);
  // The floor wins over a smaller quantum estimate.
  EXPECT_DOUBLE_EQ(EstimateNoise(x, 0.01), 0.01);
  // Noise well below the quantum cannot be resolved below q/√12.
  std::mt19937_64 rng(7);
  std::normal_distribution<double> small(0.0, 0.001);
  std::vector<double> y;
  for (int i = 0; i < 5000; ++i) y.push_back(q * std::round((0.5 * i * 1e-3 + small(rng)) / q));
  EXPECT_GE(EstimateNoise(y, 0.0), q / std::sqrt(12.0) - 1e-15);
  // A constant signal has no step at all: only the floor remains.
  EXPECT_DOUBLE_EQ(EstimateNoise(std::vector<double>(100, 3.0), 1e-4), 1e-4);
  EXPECT_DOUBLE_EQ(EstimateNoise({1.0, 2.0}, 0.5), 0.5);  // too short
}

// ------------------------------------------------------------------ preparation

TEST(PrepareLabDataset, VelocityOfARampIsExact) {
  LabDataset ds =
      PrepareLabDataset({MakeTrial("ramp", 2001, [](double t) { return 0.5 + 12.5 * t; })});
  ASSERT_EQ(ds.trials.size(), 1u);
  const LabTrial& lt = ds.trials[0];
  ASSERT_EQ(lt.velocity_mm_s.size(), 2001u);
  for (std::size_t i = 0; i < lt.velocity_mm_s.size(); ++i) {
    ASSERT_NEAR(lt.velocity_mm_s[i], 12.5, 1e-9) << "sample " << i;
    ASSERT_NEAR(lt.acceleration_mm_s2[i], 0.0, 1e-6) << "sample " << i;
  }
  // Steady motion at 12.5 mm/s never sticks, except where the velocity window is cut by
  // the trial's ends (the one-sided difference cannot see a stop there).
  for (std::size_t i = 0; i < lt.may_stick.size(); ++i) {
    const double t = lt.trial.t_s[i];
    if (t > 0.011 && t < 2.0 - 0.011) {
      ASSERT_EQ(lt.may_stick[i], 0) << "t = " << t;
    }
  }
  EXPECT_EQ(lt.may_stick.front(), 1);
  EXPECT_EQ(lt.may_stick.back(), 1);
}

TEST(PrepareLabDataset, FitIndexTakesEveryStrideThSample) {
  std::vector<formats::Trial> trials = {MakeTrial("a", 1001, [](double t) { return t; }),
                                        MakeTrial("b", 10, [](double t) { return t; })};
  LabDatasetOptions o;
  o.stride = 4;
  const LabDataset ds = PrepareLabDataset(trials, o);
  ASSERT_EQ(ds.trials[0].fit_index.size(), 251u);  // 0, 4, ..., 1000
  for (std::size_t r = 0; r < ds.trials[0].fit_index.size(); ++r)
    EXPECT_EQ(ds.trials[0].fit_index[r], 4 * r);
  EXPECT_EQ(ds.trials[1].fit_index, (std::vector<std::size_t>{0, 4, 8}));
  EXPECT_EQ(ds.residual_samples(), 254u);
  o.stride = 1;
  EXPECT_EQ(PrepareLabDataset(trials, o).residual_samples(), 1011u);
  o.stride = 0;
  ExpectContains(echoservo::testing::InvalidArgumentMessage([&] { PrepareLabDataset(trials, o); }),
                 "stride");
  o.stride = 101;
  ExpectContains(echoservo::testing::InvalidArgumentMessage([&] { PrepareLabDataset(trials, o); }),
                 "stride");
  ExpectContains(echoservo::testing::InvalidArgumentMessage([&] { PrepareLabDataset({}); }),
                 "no trials");
}

TEST(PrepareLabDataset, MayStickAroundAReversalOnly) {
  // Up at 20 mm/s, reversal at t = 1 s, down at 20 mm/s. The centred difference over
  // ±5 ms reads exactly ±20 mm/s farther than 5 ms from the reversal, passes through 0
  // at it; the stop is then widened by ±5 ms (a brief stop is smeared over the window).
  LabDataset ds = PrepareLabDataset(
      {MakeTrial("vee", 2001, [](double t) { return 20.0 * (1.0 - std::abs(t - 1.0)); })});
  const LabTrial& lt = ds.trials[0];
  int stuck_near = 0;
  for (std::size_t i = 0; i < lt.trial.size(); ++i) {
    const double t = lt.trial.t_s[i];
    const double from_reversal = std::abs(t - 1.0);
    if (from_reversal <= 0.0045) {
      EXPECT_EQ(lt.may_stick[i], 1) << "t = " << t;
      ++stuck_near;
    } else if (from_reversal >= 0.007 && t > 0.011 && t < 2.0 - 0.011) {
      EXPECT_EQ(lt.may_stick[i], 0) << "t = " << t;
      EXPECT_NEAR(std::abs(lt.velocity_mm_s[i]), 20.0, 1e-9) << "t = " << t;
    }
  }
  EXPECT_EQ(stuck_near, 9);
  // The velocity changes sign across the reversal.
  EXPECT_GT(lt.velocity_mm_s[990], 0.0);
  EXPECT_LT(lt.velocity_mm_s[1010], 0.0);
  // A base at rest may stick everywhere.
  const LabDataset rest = PrepareLabDataset({MakeTrial("rest", 500, [](double) { return 1.0; })});
  for (std::uint8_t s : rest.trials[0].may_stick) EXPECT_EQ(s, 1);
}

TEST(PrepareLabDataset, NoiseIsTheMedianOverTrials) {
  std::mt19937_64 rng(3);
  std::vector<formats::Trial> trials;
  for (double sigma : {0.01, 0.02, 0.05}) {
    std::normal_distribution<double> normal(0.0, sigma);
    formats::Trial t = MakeTrial(std::to_string(sigma), 5000, [](double x) { return std::sin(x); });
    for (double& v : t.tip_mm) v += normal(rng);
    for (double& v : t.force_n) v += 0.1 * normal(rng);
    trials.push_back(std::move(t));
  }
  const LabDataset ds = PrepareLabDataset(std::move(trials));
  EXPECT_NEAR(ds.noise.tip_mm, 0.02, 0.002);
  EXPECT_NEAR(ds.noise.force_n, 0.002, 0.0002);
}

// ------------------------------------------------------------------ LoadLabDataset

class LoadLabDatasetBad : public ::testing::TestWithParam<BadTrial> {
 protected:
  // Three good trials and one ("trial_1_bad") corrupted.
  void Write(const fs::path& dir) const {
    for (const char* name : {"trial_0", "trial_1_bad", "trial_2", "trial_3"}) {
      formats::WriteTrial(dir,
                          MakeTrial(name, 300, [](double t) { return 4.0 * std::sin(5.0 * t); }));
    }
    GetParam().corrupt(dir / "trial_1_bad.csv");
  }
};

TEST_P(LoadLabDatasetBad, ThrowsNamingTheFileUnlessSkipped) {
  TempDir dir("lab_dataset", /*create=*/true);
  Write(dir.path());
  try {
    LoadLabDataset(dir.path());
    ADD_FAILURE() << "no error for " << GetParam().name;
  } catch (const formats::TrialFormatError& e) {
    ExpectContains(e.what(), "trial_1_bad");
    for (const std::string& part : GetParam().expected) ExpectContains(e.what(), part);
  }

  LabDatasetOptions o;
  o.skip_bad = true;
  const LabDataset ds = LoadLabDataset(dir.path(), o);
  ASSERT_EQ(ds.trials.size(), 3u);
  EXPECT_EQ(ds.trials[0].trial.name, "trial_0");
  EXPECT_EQ(ds.trials[1].trial.name, "trial_2");
  EXPECT_EQ(ds.trials[2].trial.name, "trial_3");
  ASSERT_EQ(ds.skipped.size(), 1u);
  ExpectContains(ds.skipped[0], "trial_1_bad");
  for (const std::string& part : GetParam().expected) ExpectContains(ds.skipped[0], part);
  EXPECT_GT(ds.noise.tip_mm, 0.0);
}

TEST_P(LoadLabDatasetBad, AllBadThrowsEvenWhenSkipping) {
  TempDir dir("lab_dataset", /*create=*/true);
  formats::WriteTrial(dir.path(), MakeTrial("trial_1_bad", 300, [](double t) { return t; }));
  GetParam().corrupt(dir.path() / "trial_1_bad.csv");
  LabDatasetOptions o;
  o.skip_bad = true;
  try {
    LoadLabDataset(dir.path(), o);
    ADD_FAILURE() << "no error for an all-bad dataset";
  } catch (const formats::TrialFormatError& e) {
    ExpectContains(e.what(), "no valid trial");
    ExpectContains(e.what(), "1 skipped");
  }
}

INSTANTIATE_TEST_SUITE_P(
    Kinds, LoadLabDatasetBad,
    ::testing::Values(
        // Line 8 is the 7th sample; column 3 is `tip`.
        BadTrial{"NonNumericCell",
                 BadCell(8, 3, "abc"),
                 {".csv", "line 8", "column 'tip'", "not a number", "abc"}},
        BadTrial{"NaN", BadCell(12, 4, "nan"), {".csv", "line 12", "column 'force'", "NaN"}},
        BadTrial{"NonMonotonicTime",
                 BadCell(20, 0, "0.005"),
                 {".csv", "line 20", "strictly increasing"}},
        BadTrial{"MissingColumn",
                 MissingLastColumn(),  // drops `force`
                 {".csv", "line 1", "missing required column 'force'"}},
        BadTrial{"MissingJsonSidecar", MissingJsonSidecar(), {"trial_1_bad.json", "JSON"}},
        BadTrial{"MalformedJson",
                 MalformedJsonSidecar("{\"sheath_id_mm\": 2.38, \"guidewire_od_mm\": "),
                 {"trial_1_bad.json", "JSON parse error"}}),
    echoservo::testing::BadTrialName);

TEST(LoadLabDataset, MissingFolderNamesIt) {
  const fs::path missing = fs::temp_directory_path() / "echoservo_no_such_dataset_folder";
  for (bool skip : {false, true}) {
    LabDatasetOptions o;
    o.skip_bad = skip;
    try {
      LoadLabDataset(missing, o);
      ADD_FAILURE() << "no error";
    } catch (const formats::TrialFormatError& e) {
      ExpectContains(e.what(), "echoservo_no_such_dataset_folder");
      ExpectContains(e.what(), "not found");
    }
  }
}

}  // namespace
}  // namespace echoservo::lab
