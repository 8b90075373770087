#pragma once
// A Martin & Moyce water column, coarse (dx = a/10), in a slab that is
// periodic in y: the periodic case of test_periodic and test_distributed.
#include "sphnl/case.hpp"

namespace sphnl::test {

inline constexpr double kSlabColumnWidth = 2.25 * 0.0254;  // a (m)
inline constexpr double kSlabDx = kSlabColumnWidth / 10;

inline CaseGeometry periodic_slab_geometry() {
  const double a = kSlabColumnWidth, dx = kSlabDx;
  CaseGeometry g;
  g.tank = Box{{0, 0, 0}, {4.5 * a, 10 * dx, 2 * a + 2 * dx}};
  g.water = {Box{{0, 0, 0}, {a, 10 * dx, 2 * a}}};
  g.still_water_depth = 2 * a;
  g.periodic_y = true;
  return g;
}

}  // namespace sphnl::test
