#include "link/sample_validation.h"

#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "tests/link/link_test_util.h"
#include "tests/test_util/expect_error.h"

namespace echoservo::link {
namespace {

using echoservo::testing::MakeCommand;
using echoservo::testing::MakeState;
using echoservo::testing::MakeTarget;

constexpr double kNowS = 1.7e9;  // the receiver's clock
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

template <class Sample>
struct BadCase {
  std::string name;
  std::function<void(Sample&)> spoil;
  Rejection expected;
};

// Each case spoils one field of a valid sample; Check() names the reason and a validator
// counts exactly one rejection of that reason.
template <class Sample>
void ExpectRejected(const Sample& good, const std::vector<BadCase<Sample>>& cases) {
  const ValidationLimits limits;
  ASSERT_FALSE(Check(good, kNowS, limits).has_value());
  SampleValidator validator(limits);
  for (const BadCase<Sample>& c : cases) {
    Sample s = good;
    c.spoil(s);
    const std::optional<Rejection> r = Check(s, kNowS, limits);
    ASSERT_TRUE(r.has_value()) << c.name;
    EXPECT_EQ(*r, c.expected) << c.name << ": " << ToString(*r);
    const std::uint64_t before = validator.counters().count(c.expected);
    EXPECT_FALSE(validator.Accept(s, kNowS)) << c.name;
    EXPECT_EQ(validator.counters().count(c.expected), before + 1) << c.name;
  }
  EXPECT_TRUE(validator.Accept(good, kNowS));
  EXPECT_EQ(validator.counters().accepted, 1u);
  EXPECT_EQ(validator.counters().total_rejected(), cases.size());
}

TEST(SampleValidation, TargetBadCasesRejectedByReason) {
  const ValidationLimits l;
  const TargetEstimateSample good = MakeTarget(7, kNowS - 0.05);
  std::vector<BadCase<TargetEstimateSample>> cases = {
      {"NaN target", [](auto& s) { s.target_mm.y() = kNaN; }, Rejection::kNonFinite},
      {"inf tip", [](auto& s) { s.tip_mm.x() = kInf; }, Rejection::kNonFinite},
      {"NaN axis", [](auto& s) { s.axis.z() = kNaN; }, Rejection::kNonFinite},
      {"NaN harmonic", [](auto& s) { s.motion.sin_mm[1] = kNaN; }, Rejection::kNonFinite},
      {"NaN confidence", [](auto& s) { s.confidence = kNaN; }, Rejection::kNonFinite},
      {"inf validity", [](auto& s) { s.motion.valid_until_s = kInf; }, Rejection::kNonFinite},
      {"NaN acquisition", [](auto& s) { s.acquisition_time_s = kNaN; }, Rejection::kNonFinite},
      {"target beyond range", [&](auto& s) { s.target_mm.x() = l.max_abs_position_mm + 1.0; },
       Rejection::kOutOfRange},
      {"tip beyond range", [&](auto& s) { s.tip_mm.z() = -2.0 * l.max_abs_position_mm; },
       Rejection::kOutOfRange},
      {"axis not unit", [](auto& s) { s.axis *= 2.0; }, Rejection::kOutOfRange},
      {"frequency low", [&](auto& s) { s.motion.frequency_hz = 0.5 * l.min_frequency_hz; },
       Rejection::kOutOfRange},
      {"frequency high", [&](auto& s) { s.motion.frequency_hz = 2.0 * l.max_frequency_hz; },
       Rejection::kOutOfRange},
      {"confidence above 1", [](auto& s) { s.confidence = 1.5; }, Rejection::kOutOfRange},
      {"confidence negative", [](auto& s) { s.confidence = -0.1; }, Rejection::kOutOfRange},
      {"harmonic beyond range", [&](auto& s) { s.motion.cos_mm[0] = 3.0 * l.max_abs_position_mm; },
       Rejection::kOutOfRange},
      {"validity before acquisition",
       [](auto& s) { s.motion.valid_until_s = s.acquisition_time_s - 0.1; },
       Rejection::kOutOfRange},
      {"validity horizon too long",
       [&](auto& s) { s.motion.valid_until_s += 2.0 * l.max_horizon_s; }, Rejection::kOutOfRange},
      {"cos/sin sizes differ", [](auto& s) { s.motion.sin_mm.pop_back(); },
       Rejection::kBadMotionModel},
      {"too many harmonics",
       [](auto& s) {
         s.motion.cos_mm.assign(kMaxHarmonics + 1, 0.1);
         s.motion.sin_mm.assign(kMaxHarmonics + 1, 0.1);
       },
       Rejection::kBadMotionModel},
      {"acquired in the future",
       [&](auto& s) {
         s.acquisition_time_s = kNowS + 10.0 * l.max_future_s;
         s.publication_time_s = s.acquisition_time_s;
         s.motion.t0_s = s.acquisition_time_s;
         s.motion.valid_until_s = s.acquisition_time_s + 0.5;
       },
       Rejection::kFutureTimestamp},
      {"published in the future",
       [&](auto& s) { s.publication_time_s = kNowS + 10.0 * l.max_future_s; },
       Rejection::kFutureTimestamp},
      {"stale",
       [&](auto& s) {
         s.acquisition_time_s = kNowS - 2.0 * l.max_target_age_s;
         s.publication_time_s = s.acquisition_time_s;
         s.motion.t0_s = s.acquisition_time_s;
         s.motion.valid_until_s = s.acquisition_time_s + 0.5;
       },
       Rejection::kStaleTimestamp},
      {"published before acquired",
       [](auto& s) { s.publication_time_s = s.acquisition_time_s - 0.01; },
       Rejection::kPublishedBeforeAcquired},
  };
  ExpectRejected(good, cases);
}

TEST(SampleValidation, StateBadCasesRejectedByReason) {
  const ValidationLimits l;
  const CatheterStateSample good = MakeState(3, kNowS - 0.01);
  std::vector<BadCase<CatheterStateSample>> cases = {
      {"NaN base", [](auto& s) { s.base_mm = kNaN; }, Rejection::kNonFinite},
      {"inf force", [](auto& s) { s.force_n = -kInf; }, Rejection::kNonFinite},
      {"NaN stamp", [](auto& s) { s.stamp_s = kNaN; }, Rejection::kNonFinite},
      {"unknown mode", [](auto& s) { s.mode = static_cast<ServoMode>(kMaxServoMode + 1); },
       Rejection::kOutOfRange},
      {"unknown fault bit", [](auto& s) { s.faults = fault::kAll + 1; }, Rejection::kOutOfRange},
      {"base beyond range", [&](auto& s) { s.base_mm = 2.0 * l.max_abs_position_mm; },
       Rejection::kOutOfRange},
      {"force beyond range", [&](auto& s) { s.force_n = 2.0 * l.max_abs_force_n; },
       Rejection::kOutOfRange},
      {"negative estimate age", [](auto& s) { s.estimate_age_s = -1.0; }, Rejection::kOutOfRange},
      {"standoff beyond range", [&](auto& s) { s.standoff_mm = l.max_standoff_mm + 1.0; },
       Rejection::kOutOfRange},
      {"stamped in the future", [&](auto& s) { s.stamp_s = kNowS + 10.0 * l.max_future_s; },
       Rejection::kFutureTimestamp},
      {"stale", [&](auto& s) { s.stamp_s = kNowS - 2.0 * l.max_state_age_s; },
       Rejection::kStaleTimestamp},
  };
  ExpectRejected(good, cases);
}

TEST(SampleValidation, CommandBadCasesRejectedByReason) {
  const ValidationLimits l;
  const ServoCommandSample good = MakeCommand(1, kNowS - 0.01, ServoAction::kEnable);
  std::vector<BadCase<ServoCommandSample>> cases = {
      {"NaN standoff", [](auto& s) { s.standoff_mm = kNaN; }, Rejection::kNonFinite},
      {"NaN stamp", [](auto& s) { s.stamp_s = kNaN; }, Rejection::kNonFinite},
      {"action 0", [](auto& s) { s.action = static_cast<ServoAction>(0); }, Rejection::kOutOfRange},
      {"unknown action", [](auto& s) { s.action = static_cast<ServoAction>(kMaxServoAction + 1); },
       Rejection::kOutOfRange},
      {"standoff too large", [&](auto& s) { s.standoff_mm = l.max_standoff_mm + 1.0; },
       Rejection::kOutOfRange},
      {"negative standoff", [&](auto& s) { s.standoff_mm = l.min_standoff_mm - 1.0; },
       Rejection::kOutOfRange},
      {"issued in the future", [&](auto& s) { s.stamp_s = kNowS + 10.0 * l.max_future_s; },
       Rejection::kFutureTimestamp},
      {"stale (an old ENABLE)", [&](auto& s) { s.stamp_s = kNowS - 2.0 * l.max_command_age_s; },
       Rejection::kStaleTimestamp},
  };
  ExpectRejected(good, cases);
}

TEST(SampleValidation, StandoffIgnoredByStop) {
  ServoCommandSample stop = MakeCommand(2, kNowS, ServoAction::kStop);
  stop.standoff_mm = ValidationLimits{}.max_standoff_mm * 10.0;
  EXPECT_FALSE(Check(stop, kNowS, ValidationLimits{}).has_value());
}

TEST(SampleValidation, EveryReasonHasAName) {
  for (int r = 0; r < static_cast<int>(Rejection::kCount); ++r) {
    EXPECT_NE(ToString(static_cast<Rejection>(r)), "unknown");
  }
}

TEST(SampleValidation, BadLimitsThrowNamingTheField) {
  ValidationLimits l;
  l.max_frequency_hz = 0.5 * l.min_frequency_hz;
  echoservo::testing::ExpectContains(
      echoservo::testing::InvalidArgumentMessage([&] { l.Validate(); }), "max_frequency_hz");
  ValidationLimits nan_age;
  nan_age.max_target_age_s = kNaN;
  echoservo::testing::ExpectContains(
      echoservo::testing::InvalidArgumentMessage([&] { SampleValidator v(nan_age); }),
      "max_target_age_s");
}

}  // namespace
}  // namespace echoservo::link
