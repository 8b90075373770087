// Verlet lists VL_C and VL_X (paper §2.5): at every step of a dam break they
// must yield exactly the pairs with r < 2h that a cell-linked search of the
// same positions yields, and the runs must agree with the CLL run per particle
// id up to round-off (only the summation order differs).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <unordered_map>
#include <utility>
#include <vector>

#include "sphnl/neighbours/cell_linked_list.hpp"
#include "sphnl/neighbours/particle_grid.hpp"
#include "sphnl/neighbours/verlet_list.hpp"
#include "sphnl/simulation.hpp"
#include "support/pair_recorder.hpp"

using namespace sphnl;
using namespace sphnl::test;

namespace {

constexpr long kParticles = 4000;

RunConfig dam_break(ListKind list, int list_steps, double skin_factor = 0) {
  RunConfig c;
  c.particles = kParticles;
  c.progress = false;
  c.list = list;
  c.list_steps = list_steps;
  c.skin_factor = skin_factor;
  return c;
}

/// Runs `steps` steps; before each, compares the pairs the simulation's list
/// yields with a fresh cell-linked search (cells of 2h, no reordering).
void expect_same_pairs_as_cll(Simulation& sim, int steps) {
  ParticleGrid grid(sim.case_info().domain, CellOrderKind::sort_x, GridderKind::B, {});
  CellLinkedList cll;
  std::vector<std::array<double, 6>> listed, truth;
  std::vector<PairRecorder> rec_list{PairRecorder{&listed}}, rec_truth{PairRecorder{&truth}};
  for (int s = 0; s < steps; ++s) {
    sim.build_neighbours();
    listed.clear();
    truth.clear();
    sim.for_each_pair(rec_list);
    grid.build(sim.particles(), 2.0 * sim.physics().h(), false);
    cll.for_each_pair(grid, sim.particles(), rec_truth, sim.physics().kernel.support2);
    ASSERT_EQ(listed.size(), truth.size()) << "step " << s;
    ASSERT_TRUE(recorded_ids(sim.particles(), listed) == recorded_ids(sim.particles(), truth)) << "pair sets differ at step " << s;
    sim.step();
  }
}

/// Largest |a - b| over particle ids of positions, velocities and densities.
struct FieldDiff {
  double position = 0, velocity = 0, density = 0;
};
FieldDiff compare_by_id(const ParticleSet& a, const ParticleSet& b) {
  std::vector<std::uint32_t> where(b.size());
  for (std::uint32_t i = 0; i < b.size(); ++i) where[b.id[i]] = i;
  FieldDiff d;
  for (std::uint32_t i = 0; i < a.size(); ++i) {
    const std::uint32_t j = where[a.id[i]];
    d.position = std::max({d.position, std::fabs(a.x[i] - b.x[j]), std::fabs(a.y[i] - b.y[j]), std::fabs(a.z[i] - b.z[j])});
    d.velocity = std::max({d.velocity, std::fabs(a.vx[i] - b.vx[j]), std::fabs(a.vy[i] - b.vy[j]), std::fabs(a.vz[i] - b.vz[j])});
    d.density = std::max(d.density, std::fabs(a.rho[i] - b.rho[j]));
  }
  return d;
}

}  // namespace

TEST(VerletList, VlxYieldsTheCllPairSetAtEveryStep) {
  Simulation sim(dam_break(ListKind::vlx, 7));
  expect_same_pairs_as_cll(sim, 300);
  const NeighbourStats& s = sim.neighbour_stats();
  EXPECT_LT(s.builds, 300u / 2) << "VL_X with n_s = 7 should keep its lists for several steps";
  EXPECT_GT(s.max_steps_per_list, 1u);
}

TEST(VerletList, VlcWithPaperSkinYieldsTheCllPairSetAtEveryStep) {
  Simulation sim(dam_break(ListKind::vlc, 7));  // nu = 1.2, as the paper suggests
  expect_same_pairs_as_cll(sim, 200);
  const NeighbourStats& s = sim.neighbour_stats();
  EXPECT_EQ(s.builds, 200u / 7 + 1) << "VL_C rebuilds every C steps, no more and no less";
  EXPECT_EQ(s.max_steps_per_list, 7u);
}

TEST(VerletList, VerifyModeReportsTheMissesOfATooThinVlcSkin) {
  // nu = 0.02 with C = 20: the list is far too thin for 20 steps and must miss pairs;
  // verify_lists counts them instead of hiding them.
  RunConfig c = dam_break(ListKind::vlc, 20, 0.02);
  c.verify_lists = true;
  Simulation sim(c);
  for (int s = 0; s < 150; ++s) sim.step();
  EXPECT_EQ(sim.neighbour_stats().verified_steps, 150u);
  EXPECT_GT(sim.neighbour_stats().vl_misses, 0u);
}

TEST(VerletList, VerifyModeFindsNoMissesForVlx) {
  RunConfig c = dam_break(ListKind::vlx, 15);
  c.verify_lists = true;
  Simulation sim(c);
  for (int s = 0; s < 150; ++s) sim.step();
  EXPECT_EQ(sim.neighbour_stats().verified_steps, 150u);
  EXPECT_EQ(sim.neighbour_stats().vl_misses, 0u);
}

TEST(VerletList, PerIdFieldsMatchTheCllRunToRoundOff) {
  Simulation cll(dam_break(ListKind::cll, 1)), vlx(dam_break(ListKind::vlx, 7)), vlc(dam_break(ListKind::vlc, 7));
  for (int s = 0; s < 200; ++s) {
    cll.step();
    vlx.step();
    vlc.step();
  }
  for (const Simulation* vl : {&vlx, &vlc}) {
    const FieldDiff d = compare_by_id(cll.particles(), vl->particles());
    EXPECT_LT(d.position, 1e-10) << to_string(vl->config().list);
    EXPECT_LT(d.velocity, 1e-8) << to_string(vl->config().list);
    EXPECT_LT(d.density, 1e-8) << to_string(vl->config().list);
    EXPECT_NEAR(vl->time(), cll.time(), 1e-12);
  }
}

TEST(VerletList, VlxRebuildsFallAsTheSkinGrows) {
  std::vector<std::uint64_t> builds;
  for (int ns : {1, 3, 7, 15}) {
    Simulation sim(dam_break(ListKind::vlx, ns));
    for (int s = 0; s < 200; ++s) sim.step();
    builds.push_back(sim.neighbour_stats().builds);
    EXPECT_NEAR(sim.neighbour_stats().mean_steps_per_list(), 200.0 / static_cast<double>(builds.back()), 1e-12);
  }
  for (std::size_t k = 1; k < builds.size(); ++k)
    EXPECT_LT(builds[k], builds[k - 1]) << "n_s index " << k;
}

TEST(VerletList, ListMemoryIsCountedAndGrowsWithTheSkin) {
  Simulation cll(dam_break(ListKind::cll, 1)), thin(dam_break(ListKind::vlx, 2)), thick(dam_break(ListKind::vlx, 15));
  for (int s = 0; s < 100; ++s) {
    cll.step();
    thin.step();
    thick.step();
  }
  const NeighbourStats &a = thin.neighbour_stats(), &b = thick.neighbour_stats();
  const std::size_t n = thin.particles().size();
  EXPECT_GE(a.list_bytes, (n + 1 + a.list_pairs) * sizeof(std::uint32_t));
  EXPECT_GT(b.skin, a.skin);
  EXPECT_GT(b.list_pairs, a.list_pairs);
  EXPECT_GT(thin.neighbour_bytes(), a.list_bytes);
  EXPECT_GT(a.list_bytes, cll.neighbour_bytes()) << "a Verlet list outweighs the cell-linked list's grid (Fig. 15)";
  // Candidates per interaction: a thicker skin tests more 'false' candidates (§2.5).
  const auto ratio = [](const NeighbourStats& s) { return double(s.interactions) / double(s.candidates); };
  EXPECT_LT(ratio(b), ratio(a));
  EXPECT_LE(ratio(a), 1.0);
}

TEST(VerletList, OneThreadRebuildsIntoTheSameBuffer) {
  // A rebuild of the same particles reuses the list's memory: after the first
  // build a long run's builds allocate (and first-touch) nothing, and one
  // thread keeps one buffer, not two that alternate.
  Simulation sim(dam_break(ListKind::cll, 1));
  ParticleSet ps = sim.particles();
  ParticleGrid grid(sim.case_info().domain, CellOrderKind::sort_x, GridderKind::B, {});
  const double cell = 2.2 * sim.physics().h();
  grid.build(ps, cell, false);
  VerletList list;
  list.build(grid, ps, cell * cell, 1);
  const std::size_t first = list.bytes();
  ASSERT_GT(list.pairs(), 0u);
  for (int k = 0; k < 3; ++k) {
    list.build(grid, ps, cell * cell, 1);
    EXPECT_EQ(list.bytes(), first) << "build " << k + 2 << " allocated";
  }
}

TEST(VerletList, TwoThreadsGiveTheSameRunAsOne) {
  RunConfig one = dam_break(ListKind::vlx, 7), two = one;
  two.threads = 2;
  Simulation a(one), b(two);
  for (int s = 0; s < 50; ++s) {
    a.step();
    b.step();
  }
  EXPECT_EQ(a.neighbour_stats().interactions, b.neighbour_stats().interactions);
  const FieldDiff d = compare_by_id(a.particles(), b.particles());
  EXPECT_LT(d.position, 1e-12);
  EXPECT_LT(d.density, 1e-9);
}

TEST(VerletList, RejectsListStepsBelowOne) {
  EXPECT_THROW(Simulation(dam_break(ListKind::vlx, 0)), ConfigError);
}
