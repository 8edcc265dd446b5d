// Geometry of the guidewire–sheath transmission.
//
// A catheter is a guidewire of outer diameter `guidewire_od_mm` sliding inside a
// sheath of inner diameter `sheath_id_mm`, laid along a path with a list of bends
// (each an angle in degrees and a radius in mm), with a normal force `tip_load_n`
// pressing the sheath against the guidewire near the tip (a seal or tissue contact).
// Units: mm, degrees (as in the trial format), N. Derived quantities are in mm and rad.
#pragma once

#include <string>
#include <vector>

namespace echoservo::formats {

struct Bend {
  double angle_deg = 0.0;
  double radius_mm = 0.0;
};

struct CatheterConfig {
  double sheath_id_mm = 1.6;
  double guidewire_od_mm = 0.8;
  std::vector<Bend> bends;
  double tip_load_n = 0.0;

  // Radial clearance the seed's backlash law uses: D_sheath − D_guidewire (mm).
  double GapMm() const { return sheath_id_mm - guidewire_od_mm; }
  // Total bend angle θ (rad), the sum of all bend angles.
  double TotalBendRad() const;

  // Throws std::invalid_argument naming the offending field (`where` prefixes the
  // message, e.g. a file name) when the geometry is not physical.
  void Validate(const std::string& where = "catheter config") const;

  // The seed's evaluation catheter: 0.8 mm guidewire in a 1.6 mm sheath, two 90°
  // bends at radii 50 and 25 mm.
  static CatheterConfig SeedEvaluation();
};

}  // namespace echoservo::formats
