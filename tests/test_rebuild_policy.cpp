// RebuildPolicy (paper §2.5): CLL grids at every step; VL_C rebuilds exactly
// every C steps; VL_X rebuilds when some particle has moved more than dh/2
// since the build, and not before; a particle going out forces a rebuild;
// the skin is nu 2 Vmax n_s dt.
#include <gtest/gtest.h>

#include <array>
#include <random>
#include <vector>

#include "sphnl/neighbours/rebuild_policy.hpp"
#include "support/clouds.hpp"

using namespace sphnl;
using namespace sphnl::test;

namespace {

struct Fixture {
  ParticleSet ps;
  Box domain;
  ParticleGrid grid;
  VerletList verlet;
  NeighbourStats stats;
  FlowState flow;

  Fixture()
      : ps(make_cloud()), domain(bounds_of(ps, 0.5)), grid(domain, CellOrderKind::sort_x, GridderKind::B, {}) {
    flow.h = 0.1;
    flow.dt = 1e-3;
    flow.max_speed = 2.0;
    flow.cfl = 0.3;
    flow.c0 = 20;
    flow.gravity = 9.81;
  }
  static ParticleSet make_cloud() {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<std::array<double, 3>> p;
    for (int i = 0; i < 500; ++i) p.push_back({u(rng), u(rng), u(rng)});
    return cloud_from(p);
  }
};

RebuildSettings settings(ListKind list, int list_steps, double nu = 1.0) {
  RebuildSettings s;
  s.list = list;
  s.list_steps = list_steps;
  s.skin_factor = nu;
  s.reorder = false;
  return s;
}

}  // namespace

TEST(RebuildPolicy, CellLinkedListGridsEveryStep) {
  Fixture f;
  RebuildPolicy policy(settings(ListKind::cll, 1));
  for (int s = 0; s < 5; ++s) policy.prepare(f.ps, f.grid, f.verlet, f.flow, f.stats);
  EXPECT_EQ(f.stats.builds, 5u);
  EXPECT_EQ(f.stats.list_steps, 0u);
  EXPECT_EQ(f.grid.grid().cell_size, 2 * f.flow.h);
}

TEST(RebuildPolicy, SkinIsNuTwoVmaxStepsDt) {
  Fixture f;
  RebuildPolicy policy(settings(ListKind::vlc, 7, 1.2));
  EXPECT_DOUBLE_EQ(policy.skin(f.flow), 1.2 * 2 * 2.0 * 7 * 1e-3);
  f.flow.dt = 0;  // before the first step: CFL h / c0 and at least free fall g n_s dt
  f.flow.max_speed = 0;
  const double dt = 0.3 * 0.1 / 20;
  EXPECT_DOUBLE_EQ(policy.skin(f.flow), 1.2 * 2 * (9.81 * 7 * dt) * 7 * dt);
}

TEST(RebuildPolicy, VlcRebuildsExactlyEveryCSteps) {
  Fixture f;
  RebuildPolicy policy(settings(ListKind::vlc, 4));
  for (int s = 0; s < 12; ++s) policy.prepare(f.ps, f.grid, f.verlet, f.flow, f.stats);
  EXPECT_EQ(f.stats.builds, 3u);  // steps 0, 4, 8
  EXPECT_EQ(f.stats.list_steps, 12u);
  EXPECT_EQ(f.stats.max_steps_per_list, 4u);
  EXPECT_GT(f.stats.list_pairs, 0u);
  // the particles did not move: three builds stored the same pairs
  EXPECT_EQ(f.stats.list_pairs_built, 3u * f.stats.list_pairs);
  EXPECT_DOUBLE_EQ(f.grid.grid().cell_size, 2 * f.flow.h + f.stats.skin);
}

TEST(RebuildPolicy, VlxRebuildsOnlyOnceAParticleMovedMoreThanHalfTheSkin) {
  Fixture f;
  RebuildPolicy policy(settings(ListKind::vlx, 10));
  policy.prepare(f.ps, f.grid, f.verlet, f.flow, f.stats);
  ASSERT_EQ(f.stats.builds, 1u);
  const double half = 0.5 * f.stats.skin;
  f.ps.x[17] += 0.99 * half;  // not yet
  policy.prepare(f.ps, f.grid, f.verlet, f.flow, f.stats);
  EXPECT_EQ(f.stats.builds, 1u);
  f.ps.x[17] += 0.02 * half;  // now beyond dh/2
  policy.prepare(f.ps, f.grid, f.verlet, f.flow, f.stats);
  EXPECT_EQ(f.stats.builds, 2u);
  EXPECT_EQ(f.stats.forced_rebuilds, 0u);
}

TEST(RebuildPolicy, ALostParticleForcesARebuildAndInvalidateToo) {
  Fixture f;
  RebuildPolicy policy(settings(ListKind::vlc, 100));
  policy.prepare(f.ps, f.grid, f.verlet, f.flow, f.stats);
  f.ps.type[3] = ParticleType::out;
  f.flow.lost = 1;
  policy.prepare(f.ps, f.grid, f.verlet, f.flow, f.stats);
  EXPECT_EQ(f.stats.builds, 2u);
  EXPECT_EQ(f.stats.forced_rebuilds, 1u);
  policy.prepare(f.ps, f.grid, f.verlet, f.flow, f.stats);
  EXPECT_EQ(f.stats.builds, 2u);
  policy.invalidate();
  policy.prepare(f.ps, f.grid, f.verlet, f.flow, f.stats);
  EXPECT_EQ(f.stats.builds, 3u);
  EXPECT_EQ(f.stats.forced_rebuilds, 1u) << "a restored state is not a forced rebuild";
}
