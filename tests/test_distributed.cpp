// The distributed solver (parallel/domain_exchange.hpp) with P ranks as
// threads of this process (ThreadCommunicator), against the serial run: the
// same particles and total mass, positions within 1e-8 m after 30 steps
// (fewer where a scenario needs fewer).
// tests/mpi/test_mpi_ranks.cpp runs the same scenarios as MPI processes.
#include <gtest/gtest.h>

#include "support/distributed_runs.hpp"
#include "support/periodic_slab.hpp"

namespace sphnl::test {
namespace {

void expect_ranks_match_serial(const Scenario& sc, std::initializer_list<int> ranks) {
  const Outcome serial = run_scenario(sc, nullptr);
  for (const int p : ranks) {
    SCOPED_TRACE("P = " + std::to_string(p));
    const Outcome dist = run_threads(sc, p);
    expect_same_run(serial, dist);
    EXPECT_TRUE(dist.builds_equal);
    EXPECT_EQ(dist.builds, serial.builds);  // every rank rebuilds exactly when the serial run does
  }
}

/// The small dam break with `list` for 30 steps: 4 lifetimes of a Verlet list
/// (n_s = 7), and positions compared to 1e-8 m after every particle moved.
Scenario list_scenario(ListKind list) {
  Scenario sc = scenario_with(list);
  sc.steps = 30;
  return sc;
}

TEST(Distributed, CellLinkedListMatchesSerial) { expect_ranks_match_serial(list_scenario(ListKind::cll), {2, 3, 4}); }

// The lists with two rank counts each (an even and an odd split; CLL has all three).
TEST(Distributed, VerletListCMatchesSerial) { expect_ranks_match_serial(list_scenario(ListKind::vlc), {2, 3}); }

TEST(Distributed, VerletListXMatchesSerial) { expect_ranks_match_serial(list_scenario(ListKind::vlx), {3, 4}); }

TEST(Distributed, HybridRanksAndThreadsMatchSerial) {
  // Two ranks of two OpenMP threads each against one process of two threads.
  Scenario sc = scenario_with(ListKind::vlx);
  sc.config.threads = 2;
  sc.steps = 20;
  expect_ranks_match_serial(sc, {2});
}

TEST(Distributed, KernelGradientCorrectionMatchesSerial) {
  Scenario sc = scenario_with(ListKind::vlx);
  sc.config.kgc = true;
  sc.steps = 20;
  expect_ranks_match_serial(sc, {3});
}

TEST(Distributed, ExtraLoopChecksumIsTheSerialOne) {
  // extra_loops' checksum (the trace sum of M_a) counts each particle once,
  // on its owner, and is summed over ranks: the serial value up to summation
  // order (a rank's ghosts hold partial M_a and must not enter it).
  Scenario sc = scenario_with(ListKind::cll);
  sc.config.extra_loops = 1;
  sc.steps = 3;
  const Outcome serial = run_scenario(sc, nullptr);
  ASSERT_GT(serial.extra_loop_checksum, 0.0);
  for (const int p : {2, 3}) {
    SCOPED_TRACE("P = " + std::to_string(p));
    const Outcome dist = run_threads(sc, p);
    EXPECT_NEAR(dist.extra_loop_checksum, serial.extra_loop_checksum, 1e-12 * serial.extra_loop_checksum);
  }
}

TEST(Distributed, EveryOrderAndGridderMatchesSerial) {
  // Every gridder and every order once, with each list (B and sort_x above).
  const std::pair<CellOrderKind, GridderKind> combos[] = {{CellOrderKind::sort_xyz, GridderKind::A},
                                                          {CellOrderKind::hilbert, GridderKind::C},
                                                          {CellOrderKind::sort_xy, GridderKind::D}};
  for (const ListKind list : {ListKind::cll, ListKind::vlx})
    for (const auto& [order, g] : combos) {
      SCOPED_TRACE(std::string(to_string(list)) + " " + to_string(order) + " " + to_string(g));
      Scenario sc = scenario_with(list, order, g);
      sc.steps = 12;
      expect_ranks_match_serial(sc, {3});
    }
}

TEST(Distributed, WithoutReorderingMatchesSerial) {
  for (const ListKind list : {ListKind::cll, ListKind::vlc}) {
    Scenario sc = scenario_with(list);
    sc.config.reorder = false;
    sc.steps = 20;
    expect_ranks_match_serial(sc, {2});
  }
}

TEST(Distributed, ParticlesCrossRanksAndLeaveTheDomain) {
  for (const ListKind list : {ListKind::cll, ListKind::vlx}) {
    SCOPED_TRACE(to_string(list));
    Scenario sc = scenario_with(list);
    sc.push_out = true;
    sc.steps = 30;
    const Outcome serial = run_scenario(sc, nullptr);
    ASSERT_GT(serial.lost, 0u) << "the scenario must throw particles out";
    const Outcome dist = run_threads(sc, 3);
    expect_same_run(serial, dist);
    EXPECT_GT(dist.migrated, 0) << "particles must change rank";
  }
}

TEST(Distributed, VerletListXRebuildTriggeredByOneRank) {
  // With sort_x the last rank holds the still water behind the obstacle and
  // the walls: its particles barely move, so its rebuilds come from the others.
  Scenario sc = scenario_with(ListKind::vlx);
  const Outcome serial = run_scenario(sc, nullptr);
  const Outcome dist = run_threads(sc, 4);
  expect_same_run(serial, dist);
  EXPECT_GT(serial.builds, 1u);
  EXPECT_GT(dist.remote_rebuilds, 0);
  EXPECT_EQ(dist.builds, serial.builds);
}

TEST(Distributed, ARankWithoutFluid) {
  // Eight ranks along x: the water (x < 0.4 m of 1.6 m) is far lighter than
  // the walls and floor by count, so the ranks on the right own walls only.
  Scenario sc = scenario_with(ListKind::cll);
  sc.steps = 20;
  const Outcome serial = run_scenario(sc, nullptr);
  const Outcome dist = run_threads(sc, 8);
  EXPECT_EQ(dist.min_fluid_owned, 0) << "the scenario must leave a rank without fluid";
  expect_same_run(serial, dist);
}

TEST(Distributed, PeriodicSlabMatchesSerial) {
  // A Martin & Moyce column in a slab periodic in y (test_periodic.cpp's
  // case): ghosts across the seam come from the cells at the other side.
  for (const CellOrderKind order : {CellOrderKind::hilbert}) {
    Scenario sc = scenario_with(ListKind::cll, order);
    sc.steps = 5;
    sc.make_case = [&](PhysicsParams& phys) {
      const CaseGeometry g = periodic_slab_geometry();
      const double dx = kSlabDx;
      const RunConfig& c = sc.config;
      phys = PhysicsParams::make(c.h_coefficient * std::sqrt(3.0) * dx, g.still_water_depth, c.sound_speed_coef,
                                 c.viscosity_alpha, c.xsph_epsilon, c.cfl, c.clamp_boundary_density);
      return make_case(g, dx, Lattice::bcc, c.h_coefficient, phys);
    };
    SCOPED_TRACE(to_string(order));
    expect_ranks_match_serial(sc, {3});
  }
}

TEST(Distributed, MoreRanksThanCellsIsAClearError) {
  Scenario sc = scenario_with(ListKind::cll);
  sc.config.particles = 200;  // a coarse case: few cells, so few threads
  sc.steps = 1;
  const Simulation serial(sc.config);
  const long cells = CellGrid(serial.case_info().domain, 2.0 * serial.physics().h()).num_cells();
  ASSERT_LT(cells, 400);
  try {
    run_threads(sc, static_cast<int>(cells) + 1);
    FAIL() << cells + 1 << " ranks for a grid of " << cells << " cells must be refused";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("every rank must own at least one cell"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("fewer ranks"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sphnl::test
