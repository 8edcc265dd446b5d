#include "formats/parameter_spec.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace echoservo::formats {

std::string FormatParameterValue(double v) {
  char buf[40];
  const bool exponent_ok = !(std::fabs(v) >= 1e-4 && std::fabs(v) < 1e16);
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof buf, "%.*g", precision, v);
    const bool positional = std::string_view(buf).find('e') == std::string_view::npos;
    if (std::strtod(buf, nullptr) == v && (positional || exponent_ok)) return buf;
  }
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

void ParameterSpec::Check(double value, std::string_view owner) const {
  const std::string head = (owner.empty() ? std::string() : std::string(owner) + ": ") +
                           "parameter '" + std::string(name) + "' = " + FormatParameterValue(value);
  if (!std::isfinite(value)) throw std::invalid_argument(head + ": must be a finite number");
  if (kind == ParameterKind::kInteger && value != std::round(value))
    throw std::invalid_argument(head + ": must be an integer");
  if (kind == ParameterKind::kBool && value != 0.0 && value != 1.0)
    throw std::invalid_argument(head + ": must be 0 or 1 (a boolean)");
  if (value < min || value > max)
    throw std::invalid_argument(head + ": outside its bounds [" + FormatParameterValue(min) + ", " +
                                FormatParameterValue(max) + "]" +
                                (unit == "1" ? "" : " " + std::string(unit)));
}

}  // namespace echoservo::formats
