// Constants the tests share, so that files compiled together (unity batches) declare them
// once: the servo period, NaN and the degree.
#pragma once

#include <limits>
#include <numbers>

namespace echoservo::testing {

inline constexpr double kDt = 1e-3;  // the 1 kHz servo period (s)
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr double kDeg = std::numbers::pi / 180.0;  // rad per degree

}  // namespace echoservo::testing
