// Index ranges where a quadratic is non-positive: the rows of a voxel grid that a cylinder
// (a line's neighbourhood) can reach. Shared by the Radon levels and the echo-axis fit.
#pragma once

#include <algorithm>
#include <cmath>

namespace echoservo::tracking {

// [lo, hi] (clamped to [0, n − 1], rounded outwards) where A t² + 2 B t + C ≤ 0; false when
// empty. A ≈ 0 (degenerate): the whole range unless clearly empty.
inline bool QuadraticRange(double A, double B, double C, int n, int& lo, int& hi) {
  lo = 0;
  hi = n - 1;
  if (A <= 1e-12) return C <= 0 || std::abs(B) > 1e-12;
  const double disc = B * B - A * C;
  if (disc < 0) return false;
  const double sq = std::sqrt(disc);
  lo = std::max(0, static_cast<int>(std::floor((-B - sq) / A)));
  hi = std::min(n - 1, static_cast<int>(std::ceil((-B + sq) / A)));
  return lo <= hi;
}

}  // namespace echoservo::tracking
