#include "formats/catheter_config.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace echoservo::formats {
namespace {

TEST(CatheterConfig, SeedGeometry) {
  const CatheterConfig c = CatheterConfig::SeedEvaluation();
  EXPECT_NEAR(c.GapMm(), 0.8, 1e-12);
  EXPECT_NEAR(c.TotalBendRad(), std::numbers::pi, 1e-12);
  EXPECT_NO_THROW(c.Validate());
}

TEST(CatheterConfig, RejectsGuidewireWiderThanSheath) {
  CatheterConfig c = CatheterConfig::SeedEvaluation();
  c.guidewire_od_mm = 1.7;
  try {
    c.Validate("trial_3.json");
    FAIL() << "expected a throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("trial_3.json"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("guidewire_od_mm"), std::string::npos);
  }
}

TEST(CatheterConfig, RejectsNonPhysicalNumbers) {
  for (double bad : {0.0, -1.0, std::nan(""), HUGE_VAL}) {
    CatheterConfig c = CatheterConfig::SeedEvaluation();
    c.sheath_id_mm = bad;
    EXPECT_THROW(c.Validate(), std::invalid_argument) << bad;
    c = CatheterConfig::SeedEvaluation();
    c.bends[1].radius_mm = bad;
    EXPECT_THROW(c.Validate(), std::invalid_argument) << bad;
  }
  CatheterConfig c = CatheterConfig::SeedEvaluation();
  c.tip_load_n = -0.1;
  EXPECT_THROW(c.Validate(), std::invalid_argument);
}

}  // namespace
}  // namespace echoservo::formats
