#pragma once
// Cases: a tank with dynamic-boundary walls (floor and four sides, open top),
// solid obstacles standing on the floor, and blocks of water at rest with
// hydrostatic density. The dam break with obstacle of paper §2.2 is one.
// All particles sit on one lattice (BCC "staggered grid" or simple cubic)
// anchored at the tank corner; walls are snapped to lattice planes.
#include <cstddef>
#include <vector>

#include "sphnl/config.hpp"
#include "sphnl/grid.hpp"
#include "sphnl/particles.hpp"
#include "sphnl/physics.hpp"

namespace sphnl {

struct CaseGeometry {
  Box tank;                     // inner faces of floor and side walls; walls reach tank.hi[2]
  std::vector<Box> water;       // water at rest, hydrostatic below each block's top
  std::vector<Box> obstacles;   // solid boxes standing on the floor
  double still_water_depth = 0; // H, sets the speed of sound c0 = coef sqrt(g H)
  /// No side walls in y: the tank's y extent (snapped to the lattice) is one
  /// period, for slabs that must behave two-dimensionally (Martin & Moyce).
  bool periodic_y = false;
};

/// Paper §2.2: box 1.6 x 0.61 x 0.75 m, water 0.4 x 0.61 x 0.3 m at x = 0,
/// obstacle 0.12 x 0.12 x 0.75 m at x in [0.9, 1.02], y in [0.24, 0.36].
CaseGeometry dam_break_geometry();

struct Case {
  ParticleSet particles;        // fluid first, then boundary; id = index
  Box domain;                   // particles leaving it are `out`
  double period_y = 0;          // > 0: y is periodic over [domain.lo[1], domain.lo[1] + period_y)
  double dx = 0, h = 0;
  std::size_t n_fluid = 0, n_boundary = 0;
};

/// h = h_coefficient * sqrt(3) dx (docs/PHYSICS.md). Mass: rho dx^3 / 2 on BCC
/// (two particles per dx^3), rho dx^3 on the cubic lattice.
Case make_case(const CaseGeometry& g, double dx, Lattice lattice, double h_coefficient, const PhysicsParams& phys);
/// Fluid and boundary particles make_case would create, without creating them.
std::size_t count_particles(const CaseGeometry& g, double dx, Lattice lattice);
/// The spacing whose particle count is closest to `target`.
double dx_for_particles(const CaseGeometry& g, std::size_t target, Lattice lattice);

}  // namespace sphnl
