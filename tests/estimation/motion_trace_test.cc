// Motion traces: the CSV reader's errors (file, line, column, why), column choice, gaps,
// interpolation and resampling; the harmonic fit's recovery of a known heartbeat.
#include "estimation/motion_trace.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>

#include "estimation/harmonic_fit.h"
#include "tests/test_util/expect_error.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo::estimation {
namespace {

using echoservo::testing::ExpectContains;
using echoservo::testing::InvalidArgumentMessage;
using echoservo::testing::TempDir;

std::string Write(const TempDir& dir, const std::string& name, const std::string& text) {
  std::filesystem::create_directories(dir.path());
  const std::string path = (dir.path() / name).string();
  std::ofstream(path) << text;
  return path;
}

TEST(MotionTrace, ReadsTheFirstPositionColumnOrANamedOne) {
  TempDir dir("motion_trace");
  const std::string p = Write(dir, "a.csv", "t,x,y\n0,1,10\n0.1,2,20\n0.2,3,30\n");
  const MotionTrace a = ReadMotionTrace(p);
  EXPECT_EQ(a.column, "x");
  EXPECT_EQ(a.position_mm, (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(a.Where(1), p + ":3");
  const MotionTrace b = ReadMotionTrace(p, "y");
  EXPECT_EQ(b.position_mm, (std::vector<double>{10, 20, 30}));
}

TEST(MotionTrace, BadFilesNameTheLineColumnAndProblem) {
  TempDir dir("motion_trace");
  auto error = [&](const std::string& text, const std::string& column = "") {
    const std::string p = Write(dir, "bad.csv", text);
    return InvalidArgumentMessage([&] { ReadMotionTrace(p, column); });
  };
  ExpectContains(error(""), "empty file");
  ExpectContains(error("t,x\n"), "has 0 sample(s); a motion trace needs at least 2");
  const std::string nan = error("t,x\n0,1\n0.1,nan\n0.2,3\n");
  ExpectContains(nan, "bad.csv: line 3: column 'x'");
  ExpectContains(nan, "NaN");
  ExpectContains(error("t,x\n0,1\n0.1,2\n0.1,3\n"),
                 "line 4: column 't': times must be strictly increasing");
  ExpectContains(error("t,x\n0,1\n0.2,2\n0.1,3\n"), "line 4");
  ExpectContains(error("x,y\n0,1\n1,2\n"), "missing required column 't'");
  ExpectContains(error("t,x\n0,1\n1,2\n", "z"), "missing required column 'z'");
  ExpectContains(error("t\n0\n1\n"), "no position column");
  ExpectContains(error("t,x\n0,1\n1,abc\n"), "line 3: column 'x': not a number");
}

TEST(MotionTrace, FindsGapsAndNeverInterpolatesAcrossThem) {
  MotionTrace t;
  t.source = "mem";
  for (int i = 0; i < 20; ++i) {
    if (i >= 8 && i < 12) continue;  // 0.5 s without samples
    t.t_s.push_back(0.1 * i);
    t.position_mm.push_back(i);
  }
  ValidateMotionTrace(t);
  EXPECT_NEAR(MedianInterval(t), 0.1, 1e-12);
  ASSERT_EQ(FindGaps(t).size(), 1u);
  double x = 0.0;
  EXPECT_TRUE(InterpolateTrace(t, 0.25, x));
  EXPECT_NEAR(x, 2.5, 1e-12);
  EXPECT_FALSE(InterpolateTrace(t, 0.9, x));
  EXPECT_FALSE(InterpolateTrace(t, 5.0, x));
  const MotionTrace r = ResampleTrace(t, 20.0);  // 0.05 s steps, none inside the gap
  for (double ti : r.t_s) EXPECT_FALSE(ti > 0.7 + 1e-9 && ti < 1.2 - 1e-9) << ti;
  EXPECT_EQ(r.size(), 39u - 9u);
}

TEST(MotionTrace, InMemoryTracesAreValidated) {
  MotionTrace t;
  t.source = "mem";
  t.t_s = {0.0, 0.1, 0.1};
  t.position_mm = {0.0, 1.0, 2.0};
  ExpectContains(InvalidArgumentMessage([&] { ValidateMotionTrace(t); }),
                 "mem: sample 2: times must be strictly");
  t.t_s = {0.0, 0.1, 0.2};
  t.position_mm[1] = std::nan("");
  ExpectContains(InvalidArgumentMessage([&] { ValidateMotionTrace(t); }), "sample 1: NaN");
}

TEST(HarmonicFit, RecoversAKnownHeartbeatFromFourSeconds) {
  FourierMotion truth;
  truth.frequency_hz = 1.3;
  truth.offset_mm = 2.0;
  truth.cos_mm = {4.0, -1.0, 0.5};
  truth.sin_mm = {1.5, 0.8, -0.3};
  std::vector<double> t;
  std::vector<double> x;
  for (int i = 0; i <= 100; ++i) {
    t.push_back(i / 25.0);
    x.push_back(truth.Position(t.back()));
  }
  const HarmonicFit fit = FitHarmonics(t.data(), x.data(), t.size(), t.back(), {});
  EXPECT_EQ(fit.harmonics, 3);
  EXPECT_NEAR(fit.motion.frequency_hz, 1.3, 1e-6);
  EXPECT_EQ(fit.motion.sin_mm[0], 0.0);
  EXPECT_NEAR(fit.motion.cos_mm[0], std::hypot(4.0, 1.5), 1e-6);
  // The golden-section search resolves the rate to ~1e-7 Hz: 1e-4 mm over 4 s.
  EXPECT_LT(fit.residual_rms_mm, 1e-4);
  for (double ti : t) EXPECT_NEAR(fit.motion.Position(ti), truth.Position(ti), 1e-4);
  // One beat is needed at the lowest rate (0.6 Hz: 1.7 s).
  ExpectContains(InvalidArgumentMessage([&] { FitHarmonics(t.data(), x.data(), 30, t[29], {}); }),
                 "less than one beat");
}

TEST(FourierMotion, DriftAddsALinearTermAboutT0) {
  FourierMotion m;
  m.t0_s = 2.0;
  m.offset_mm = 1.0;
  m.drift_mm_s = 3.0;
  EXPECT_NEAR(m.Position(2.5), 2.5, 1e-12);
  EXPECT_NEAR(m.Evaluate(2.5).velocity_mm_s, 3.0, 1e-12);
  m.drift_mm_s = std::nan("");
  EXPECT_THROW(m.Validate(), std::invalid_argument);
}

}  // namespace
}  // namespace echoservo::estimation
