// Periodic y (the Martin & Moyce slab): the cell sweep finds nearest images
// across the seam; too narrow a period is refused; the slab case simulates.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "sphnl/case.hpp"
#include "sphnl/simulation.hpp"
#include "support/clouds.hpp"
#include "support/oracle.hpp"
#include "support/pair_sources.hpp"
#include "support/periodic_slab.hpp"

using namespace sphnl;
using namespace sphnl::test;

TEST(Periodic, CellSweepFindsNearestImagesAcrossTheSeam) {
  // Uniform points in a slab 3.3 radii wide in y (3 cells, the last one wider),
  // so many pairs straddle the seam; every combination must give the
  // nearest-image brute-force pairs.
  const double radius = 0.3, period = 3.3 * radius;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> ux(-1.0, 1.0), uy(0.0, period);
  std::vector<std::array<double, 3>> pts;
  for (int i = 0; i < 1200; ++i) pts.push_back({ux(rng), uy(rng), ux(rng)});
  pts.push_back({0.1, 0.0, 0.1});            // exactly on the seam
  pts.push_back({0.1, period - 0.05, 0.1});  // its neighbour across it
  const ParticleSet cloud = cloud_from(pts);
  const PairSet truth = brute_force_pairs(cloud, radius * radius, {.period_y = period});
  const PairSet plain = brute_force_pairs(cloud, radius * radius);
  ASSERT_GT(truth.size(), plain.size() + 500) << "the test needs pairs across the seam";
  Box domain = bounds_of(cloud, radius);
  domain.lo[1] = 0;
  for (GridderKind g : kGridders)
    for (CellOrderKind o : kOrders)
      for (bool reorder : {false, true}) {
        ParticleSet ps = cloud;
        EXPECT_EQ(swept_pairs(ps, domain, radius * radius, g, o, reorder, {}, period), truth) << combo(g, o, reorder);
      }
}

TEST(Periodic, NarrowPeriodIsRefusedWithTheWidthNeeded) {
  const ParticleSet cloud = cloud_from({{0, 0, 0}, {0, 0.5, 0}});
  ParticleGrid pg(Box{{-1, 0, -1}, {1, 1, 1}}, CellOrderKind::sort_x, GridderKind::B, {}, 0.55);
  ParticleSet ps = cloud;
  try {
    pg.build(ps, 0.2, false);
    FAIL() << "a period of 2.75 cells was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("at least 3"), std::string::npos) << e.what();
  }
}

TEST(Periodic, SlabCaseHasNoSideWallsAndSimulatesAcrossTheSeam) {
  // A Martin & Moyce column, coarse, in a slab that is periodic in y.
  const double dx = test::kSlabDx;
  const CaseGeometry g = test::periodic_slab_geometry();
  RunConfig c;
  c.progress = false;
  const double h = c.h_coefficient * std::sqrt(3.0) * dx;
  const PhysicsParams phys = PhysicsParams::make(h, g.still_water_depth, c.sound_speed_coef, c.viscosity_alpha,
                                                 c.xsph_epsilon, c.cfl, c.clamp_boundary_density);
  Case cs = make_case(g, dx, Lattice::bcc, c.h_coefficient, phys);
  const double period = cs.period_y;
  EXPECT_NEAR(period, 10 * dx, 1e-12);
  std::map<long, std::size_t> fluid_per_layer;  // y in half spacings -> fluid particles
  for (std::size_t i = 0; i < cs.particles.size(); ++i) {
    const double x = cs.particles.x[i], y = cs.particles.y[i], z = cs.particles.z[i];
    ASSERT_TRUE(y >= 0 && y < period) << "y " << y;
    if (cs.particles.type[i] == ParticleType::fluid)
      ++fluid_per_layer[std::lround(2 * y / dx)];
    else  // walls at x = 0 and x = 4.5a and the floor, none in y
      EXPECT_TRUE(x <= 1e-9 || x >= g.tank.hi[0] - 1e-9 || z <= 1e-9) << x << " " << y << " " << z;
  }
  ASSERT_EQ(fluid_per_layer.size(), 20u);  // 10 dx of BCC layers, each dx/2
  for (const auto& [layer, count] : fluid_per_layer)
    EXPECT_EQ(count, fluid_per_layer.at(layer % 2)) << "layer " << layer;  // translation invariant in y

  RunConfig vl = c;
  vl.list = ListKind::vlx;
  EXPECT_THROW(Simulation(vl, cs, phys), ConfigError);

  Simulation sim(c, std::move(cs), phys);
  for (int s = 0; s < 80; ++s) sim.step();
  const ParticleSet& state = sim.particles();
  for (std::size_t i = 0; i < state.size(); ++i)
    ASSERT_TRUE(state.y[i] >= 0 && state.y[i] < period) << "particle " << state.id[i] << " y " << state.y[i];
  const double support2 = sim.physics().kernel.support2;
  const PairSet truth = brute_force_pairs(state, support2, {.period_y = period});
  ASSERT_GT(truth.size(), brute_force_pairs(state, support2).size() + 100);
  GridderOptions options;
  options.dx = dx;
  options.h = sim.physics().h();
  options.particles_per_dx3 = 2;
  for (GridderKind gk : kGridders) {
    ParticleSet ps = state;
    EXPECT_EQ(swept_pairs(ps, sim.case_info().domain, support2, gk, CellOrderKind::sort_x, true, options, period), truth)
        << "gridder " << to_string(gk);
  }
  EXPECT_EQ(sim.lost(), 0u);
}
