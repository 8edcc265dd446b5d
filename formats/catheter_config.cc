#include "formats/catheter_config.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace echoservo::formats {
namespace {

void Require(bool ok, const std::string& where, const std::string& field, const std::string& why) {
  if (!ok) throw std::invalid_argument(where + ": field '" + field + "' " + why);
}

}  // namespace

double CatheterConfig::TotalBendRad() const {
  double total_deg = 0.0;
  for (const Bend& b : bends) total_deg += b.angle_deg;
  return total_deg * std::numbers::pi / 180.0;
}

void CatheterConfig::Validate(const std::string& where) const {
  Require(std::isfinite(sheath_id_mm) && sheath_id_mm > 0.0, where, "sheath_id_mm",
          "must be a finite diameter > 0 mm");
  Require(std::isfinite(guidewire_od_mm) && guidewire_od_mm > 0.0, where, "guidewire_od_mm",
          "must be a finite diameter > 0 mm");
  Require(guidewire_od_mm < sheath_id_mm, where, "guidewire_od_mm",
          "must be smaller than sheath_id_mm (the guidewire must fit inside the sheath)");
  Require(sheath_id_mm < 20.0, where, "sheath_id_mm",
          "is implausibly large for a catheter (>= 20 mm)");
  Require(std::isfinite(tip_load_n) && tip_load_n >= 0.0 && tip_load_n <= 50.0, where, "tip_load_n",
          "must be a finite normal force in [0, 50] N");
  for (std::size_t i = 0; i < bends.size(); ++i) {
    const std::string field = "bends[" + std::to_string(i) + "]";
    Require(std::isfinite(bends[i].angle_deg) && bends[i].angle_deg >= 0.0 &&
                bends[i].angle_deg <= 1080.0,
            where, field + ".angle_deg", "must be a finite angle in [0, 1080] degrees");
    Require(std::isfinite(bends[i].radius_mm) && bends[i].radius_mm > 0.0, where,
            field + ".radius_mm", "must be a finite radius > 0 mm");
  }
}

CatheterConfig CatheterConfig::SeedEvaluation() {
  CatheterConfig c;
  c.sheath_id_mm = 1.6;
  c.guidewire_od_mm = 0.8;
  c.bends = {{90.0, 50.0}, {90.0, 25.0}};
  c.tip_load_n = 0.0;
  return c;
}

}  // namespace echoservo::formats
