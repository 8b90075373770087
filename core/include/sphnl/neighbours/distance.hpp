#pragma once
// distance2: the squared distance every neighbour path and the brute-force
// oracle of the tests use, with the same rounding (fused multiply-adds where
// the target has them), so that all paths agree on pairs at exactly r = R.
#include <cmath>

namespace sphnl {

inline double distance2(double dx, double dy, double dz) {
#if defined(__FMA__)
  return std::fma(dz, dz, std::fma(dy, dy, dx * dx));
#else
  return dx * dx + dy * dy + dz * dz;
#endif
}

}  // namespace sphnl
