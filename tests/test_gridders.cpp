// Gridding algorithms A-D (paper §2.3): the same cells in the same order, gridder
// C's row length and overflow; memory accounted as the paper's Figs. 7 and 11
// need it.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "sphnl/gridders/linked_list.hpp"
#include "sphnl/gridders/preconditioned_vector.hpp"
#include "sphnl/gridders/sliding_vector.hpp"
#include "sphnl/gridders/static_matrix.hpp"
#include "sphnl/neighbours/neighbour_search.hpp"
#include "sphnl/neighbours/particle_grid.hpp"
#include "sphnl/simulation.hpp"
#include "sphnl/neighbours/cell_sweep.hpp"
#include "support/clouds.hpp"
#include "support/dam_break.hpp"
#include "support/pair_sources.hpp"

using namespace sphnl;
using namespace sphnl::test;

TEST(Gridders, AllFourHoldTheSameCellsInTheSameOrder) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::uint32_t> cell(0, 39);
  std::vector<std::uint32_t> keys(500);
  for (auto& k : keys) k = cell(rng);
  keys[3] = keys[77] = kNoCell;  // out particles are not gridded
  // Both variants of gridder A (the paper's, and shift_all), keys in random
  // order, in cell order and in reverse cell order; cell_members (the direct
  // pair loop's view) must read what gather_cell copies.
  std::vector<std::uint32_t> sorted_keys = keys, reversed_keys = keys;
  std::sort(sorted_keys.begin(), sorted_keys.end());  // kNoCell sorts last
  std::sort(reversed_keys.begin(), reversed_keys.end(), std::greater<>());
  for (const auto* key_set : {&keys, &sorted_keys, &reversed_keys}) {
    std::vector<std::vector<std::uint32_t>> perms;
    std::vector<std::string> names;
    for (GridderKind g : kGridders)
      for (SlidingVariant a : {SlidingVariant::occupied, SlidingVariant::shift_all}) {
        if (g != GridderKind::A && a == SlidingVariant::shift_all) continue;
        GridderOptions opt;
        opt.max_parts_in_cell = 64;
        opt.sliding_variant = a;
        const std::string name = std::string(to_string(g)) + (g == GridderKind::A ? std::string(" ") + to_string(a) : "");
        auto gridder = make_gridder(g, opt);
        gridder->build(*key_set, 40);
        std::vector<std::uint32_t> buf(gridder->max_cell_count()), scratch(gridder->max_cell_count()), perm;
        std::uint32_t max_count = 0;
        for (std::uint32_t k = 0; k < 40; ++k) {
          const std::uint32_t n = gridder->gather_cell(k, buf.data());
          max_count = std::max(max_count, n);
          for (std::uint32_t s = 0; s < n; ++s) EXPECT_EQ((*key_set)[buf[s]], k) << name;
          EXPECT_TRUE(std::is_sorted(buf.begin(), buf.begin() + n)) << name << ": cell " << k;
          const auto members = gridder->cell_members(k, scratch.data());
          EXPECT_TRUE(std::equal(members.begin(), members.end(), buf.begin(), buf.begin() + n) && members.size() == n)
              << name << ": cell_members of cell " << k;
        }
        EXPECT_EQ(max_count, gridder->max_cell_count()) << name;
        gridder->cell_order_permutation(perm);
        EXPECT_EQ(perm.size(), 498u) << name;
        perms.push_back(perm);
        names.push_back(name);
      }
    for (std::size_t g = 1; g < perms.size(); ++g) EXPECT_EQ(perms[g], perms[0]) << names[g];
  }
}

// Gridder B split over threads: the same CellsBegin and PartsSorted (each cell
// in increasing index) as on one thread, for scattered and sorted keys, out
// particles and more threads than the size allows.
TEST(Gridders, PreconditionedVectorSplitOverThreadsBuildsTheSameCells) {
  std::mt19937 rng(11);
  const std::uint32_t num_keys = 5003;
  std::uniform_int_distribution<std::uint32_t> cell(0, num_keys - 1);
  std::vector<std::uint32_t> keys(200000);
  for (auto& k : keys) k = cell(rng);
  for (std::size_t i = 0; i < keys.size(); i += 997) keys[i] = kNoCell;
  std::vector<std::uint32_t> sorted_keys = keys;
  std::sort(sorted_keys.begin(), sorted_keys.end());
  for (const auto* key_set : {&keys, &sorted_keys}) {
    PreconditionedVector one;
    one.build(*key_set, num_keys);
    std::vector<std::uint32_t> perm_one, perm_many;
    one.cell_order_permutation(perm_one);
    // Counting the keys gives the same CellsBegin.
    std::vector<std::uint32_t> counted(num_keys + 1, 0);
    for (const std::uint32_t k : *key_set)
      if (k != kNoCell) ++counted[k + 1];
    for (std::uint32_t k = 0; k < num_keys; ++k) counted[k + 1] += counted[k];
    EXPECT_TRUE(std::ranges::equal(one.cells_begin(), counted));
    for (int threads : {2, 3, 4, 64}) {
      PreconditionedVector many;
      many.set_threads(threads);
      many.build(*key_set, num_keys);
      EXPECT_TRUE(std::ranges::equal(many.cells_begin(), one.cells_begin())) << threads;
      EXPECT_EQ(many.max_cell_count(), one.max_cell_count()) << threads;
      many.cell_order_permutation(perm_many);
      EXPECT_EQ(perm_many, perm_one) << threads;
      for (std::uint32_t k = 0; k < num_keys; k += 101) {
        const auto a = one.cell_members(k, nullptr), b = many.cell_members(k, nullptr);
        EXPECT_TRUE(std::ranges::equal(a, b)) << threads << ": cell " << k;
      }
    }
  }
}

TEST(Gridders, StaticMatrixOverflowStopsWithTheCellAndTheOption) {
  GridderOptions opt;
  opt.max_parts_in_cell = 3;
  StaticMatrix c(opt);
  const std::vector<std::uint32_t> keys = {2, 2, 1, 2, 2, 2, 0};
  try {
    c.build(keys, 3);
    FAIL() << "an overflowing cell must not be dropped silently";
  } catch (const std::runtime_error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("cell 2"), std::string::npos) << msg;
    EXPECT_NE(msg.find("5 particles"), std::string::npos) << msg;
    EXPECT_NE(msg.find("max_parts_in_cell"), std::string::npos) << msg;
  }
  opt.max_parts_in_cell = -1;
  EXPECT_THROW(StaticMatrix{opt}, ConfigError);
}

TEST(Gridders, StaticMatrixDefaultRowFollowsTheLattice) {
  GridderOptions opt;
  opt.dx = 0.01;
  opt.h = 1.5 * 0.01;  // h = 0.866 sqrt(3) dx
  opt.particles_per_dx3 = 2;
  // A 2.2h = 3.3dx cell cuts at most 4 lattice planes per axis: 2 * 64 nodes, x 1.3.
  EXPECT_EQ(default_max_parts_in_cell(opt), 167);
  EXPECT_EQ(StaticMatrix(opt).max_parts_in_cell(), 167u);
  EXPECT_EQ(default_max_parts_in_cell(GridderOptions{}), 0);
  StaticMatrix from_data{GridderOptions{}};  // no lattice: twice the fullest cell
  from_data.build(std::vector<std::uint32_t>{0, 0, 0, 1}, 2);
  EXPECT_EQ(from_data.max_parts_in_cell(), 6u);
}

// ------------------------------------------------------------------ memory

TEST(Memory, GriddersAndOrdersReportWhatTheyAllocate) {
  Simulation sim(small_dam_break_config());
  const ParticleSet& state = sim.particles();
  GridderOptions options;
  options.dx = sim.case_info().dx;
  options.h = sim.physics().h();
  options.particles_per_dx3 = 2;
  auto grid_bytes = [&](GridderKind g, CellOrderKind o, bool reorder) {
    ParticleSet ps = state;
    ParticleGrid pg(sim.case_info().domain, o, g, options);
    pg.build(ps, 2 * sim.physics().h(), reorder);
    return std::array<std::size_t, 3>{pg.gridder().bytes(), pg.order().bytes(), pg.bytes()};
  };
  const auto b = grid_bytes(GridderKind::B, CellOrderKind::sort_x, false);
  const auto c = grid_bytes(GridderKind::C, CellOrderKind::sort_x, false);
  const auto a = grid_bytes(GridderKind::A, CellOrderKind::sort_x, false);
  const auto d = grid_bytes(GridderKind::D, CellOrderKind::sort_x, false);
  const std::size_t n = state.size();
  EXPECT_GE(b[0], n * sizeof(std::uint32_t));  // PartsSorted alone
  EXPECT_GE(a[0], n * sizeof(std::uint32_t));
  EXPECT_GE(d[0], n * sizeof(std::uint32_t));  // next[]
  EXPECT_GT(c[0], 5 * b[0]) << "a full MaxPartsInCell row for every cell (Fig. 7)";
  // Z-order pads the key space; every key-indexed array pays for it.
  const auto xyz = grid_bytes(GridderKind::B, CellOrderKind::sort_xyz, false);
  EXPECT_GT(xyz[1], b[1]);
  EXPECT_GT(xyz[0], b[0]);
  // Reordering buffers are counted once reordering has run.
  const auto reordered = grid_bytes(GridderKind::B, CellOrderKind::sort_x, true);
  EXPECT_GE(reordered[2], b[2] + n * sizeof(double));
  // The search tool's structures are accounted too.
  NeighbourSearch search(SearchOptions{GridderKind::C, CellOrderKind::sort_x, true, 0});
  NeighbourLists lists;
  search.run(state.x, state.y, state.z, 2 * sim.physics().h(), lists);
  EXPECT_GE(search.bytes(), search.gridder().bytes() + 3 * n * sizeof(double));
  EXPECT_GE(lists.bytes(), lists.num_entries() * sizeof(std::uint32_t));
}

TEST(Memory, CellSweepCountsTheThreadSplitOnce) {
  // A sparse cloud on many cells: the split's weight per key is a large part
  // of the sweep's memory, so counting it once per thread would show.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 10.0);
  std::vector<std::array<double, 3>> pts;
  for (int i = 0; i < 400; ++i) pts.push_back({u(rng), u(rng), u(rng)});
  ParticleSet ps = cloud_from(pts);
  ParticleGrid pg(bounds_of(ps, 0.1), CellOrderKind::sort_x, GridderKind::B, {});
  pg.build(ps, 0.5, false);
  const auto nothing = [](int, CellSweep::Scratch&, std::uint32_t) {};
  CellSweep one, four;
  one.run(pg.grid(), pg.order(), pg.gridder(), ps, fields::position, 1, nothing);
  four.run(pg.grid(), pg.order(), pg.gridder(), ps, fields::position, 4, nothing);
  const std::size_t keys = pg.order().num_keys();
  ASSERT_GT(keys, 8000u);
  // One thread: its scratch and 2 key bounds. Four: four such scratch sets,
  // and the split (5 key bounds, one weight per key) once.
  const std::size_t scratch = one.bytes() - 2 * sizeof(std::uint32_t);
  EXPECT_EQ(four.bytes(), 4 * scratch + 5 * sizeof(std::uint32_t) + keys * sizeof(double));
}
