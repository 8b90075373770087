// The ablations (README.md, "Ablations"): each must find exactly the
// brute-force neighbourhoods, and reach the default's particle state after
// 100 steps of a small dam break (bit for bit where the arithmetic is the
// same, to round-off where only the summation order differs); the extra
// loops' result must match an independent computation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "sphnl/simulation.hpp"
#include "support/dam_break.hpp"
#include "support/oracle.hpp"
#include "support/pair_recorder.hpp"
#include "support/simulation_state.hpp"

using namespace sphnl;
using namespace sphnl::test;

namespace {

using State = StateById;

constexpr long kParticles = 2000;  // 344 fluid: 100 steps in well under a second
constexpr int kSteps = 100;

struct Ablation {
  std::string name;
  std::function<void(RunConfig&)> set;
  /// The same pairs in the same order with the same arithmetic as the
  /// default: the state must be the same bit for bit. Otherwise only the
  /// order of the sums differs, and the state must agree to round-off.
  bool bitwise = false;
};

/// Every ablation on its own, with the gridders and lists it concerns.
std::vector<Ablation> ablations() {
  std::vector<Ablation> a;
  for (GridderKind g : {GridderKind::A, GridderKind::B, GridderKind::C, GridderKind::D})
    for (bool reorder : {false, true})
      a.push_back({std::string("pair_loop=direct gridder=") + to_string(g) + " reorder=" + (reorder ? "1" : "0"),
                   [g, reorder](RunConfig& c) {
                     c.pair_loop = PairLoopKind::direct;
                     c.gridder = g;
                     c.reorder = reorder;
                   }});
  a.push_back({"pair_loop=direct threads=2", [](RunConfig& c) {
                 c.pair_loop = PairLoopKind::direct;
                 c.threads = 2;
               }});
  // The masked j-block loop: the same pairs, summed in another order; with
  // every pair operation of a step (KGC's pre-pass and corrected force, the
  // float kernel of precision=mixed) and threads.
  for (GridderKind g : {GridderKind::B, GridderKind::D})
    for (bool reorder : {false, true})
      a.push_back({std::string("pair_loop=masked gridder=") + to_string(g) + " reorder=" + (reorder ? "1" : "0"),
                   [g, reorder](RunConfig& c) {
                     c.pair_loop = PairLoopKind::masked;
                     c.gridder = g;
                     c.reorder = reorder;
                   }});
  a.push_back({"pair_loop=masked kgc=1 threads=2", [](RunConfig& c) {
                 c.pair_loop = PairLoopKind::masked;
                 c.kgc = true;
                 c.threads = 2;
               }});
  a.push_back({"pair_loop=masked precision=mixed", [](RunConfig& c) {
                 c.pair_loop = PairLoopKind::masked;
                 c.precision = Precision::mixed;
               }});
  // On a Verlet list: every stored candidate evaluated, the distance test a
  // lane mask (interact_candidates); both lists, with KGC, threads, mixed, simd=off.
  auto masked_verlet = [](ListKind l, std::function<void(RunConfig&)> more) {
    return [l, more](RunConfig& c) {
      c.pair_loop = PairLoopKind::masked;
      c.list = l;
      c.list_steps = 5;
      more(c);
    };
  };
  for (ListKind l : {ListKind::vlc, ListKind::vlx})
    for (bool reorder : {false, true})
      a.push_back({std::string("pair_loop=masked list=") + to_string(l) + " reorder=" + (reorder ? "1" : "0"),
                   masked_verlet(l, [reorder](RunConfig& c) { c.reorder = reorder; })});
  a.push_back({"pair_loop=masked list=vlx kgc=1 threads=2", masked_verlet(ListKind::vlx, [](RunConfig& c) {
                 c.kgc = true;
                 c.threads = 2;
               })});
  a.push_back({"pair_loop=masked list=vlx thread_updates=phased threads=2",
               masked_verlet(ListKind::vlx, [](RunConfig& c) {
                 c.thread_updates = ThreadUpdates::phased;
                 c.threads = 2;
               })});
  a.push_back({"pair_loop=masked list=vlc precision=mixed",
               masked_verlet(ListKind::vlc, [](RunConfig& c) { c.precision = Precision::mixed; })});
  a.push_back({"pair_loop=masked list=vlx simd=off",
               masked_verlet(ListKind::vlx, [](RunConfig& c) { c.simd = false; })});
  for (ListKind l : {ListKind::cll, ListKind::vlx}) {
    a.push_back({std::string("simd=off list=") + to_string(l), [l](RunConfig& c) {
                   c.simd = false;
                   c.list = l;
                   c.list_steps = 5;
                 }});
    a.push_back({std::string("skip_boundary_pairs list=") + to_string(l), [l](RunConfig& c) {
                   c.skip_boundary_pairs = true;
                   c.list = l;
                   c.list_steps = 5;
                 }, true});
  }
  for (bool reorder : {false, true}) {
    a.push_back({std::string("gridder=A shift_all reorder=") + (reorder ? "1" : "0"), [reorder](RunConfig& c) {
                   c.gridder = GridderKind::A;
                   c.gridder_a_variant = SlidingVariant::shift_all;
                   c.reorder = reorder;
                 }, true});
    a.push_back({std::string("initial_order=shuffled reorder=") + (reorder ? "1" : "0"), [reorder](RunConfig& c) {
                   c.initial_order = InitialOrder::shuffled;
                   c.reorder = reorder;
                 }});
  }
  a.push_back({"extra_loops=3", [](RunConfig& c) { c.extra_loops = 3; }, true});
  return a;
}

RunConfig config_with(const Ablation& a) {
  RunConfig c = small_dam_break_config(kParticles);
  a.set(c);
  return c;
}

State run(const RunConfig& c) { return state_after(c, kSteps); }

/// The default path with everything else of `c` (list, reordering, threads).
RunConfig reference_of(RunConfig c) {
  const RunConfig defaults;
  c.pair_loop = defaults.pair_loop;
  c.simd = defaults.simd;
  c.skip_boundary_pairs = defaults.skip_boundary_pairs;
  c.gridder_a_variant = defaults.gridder_a_variant;
  c.initial_order = defaults.initial_order;
  c.extra_loops = defaults.extra_loops;
  return c;
}

}  // namespace

TEST(Ablations, NeighbourhoodsMatchBruteForce) {
  for (const Ablation& a : ablations()) {
    Simulation sim(config_with(a));
    const double support2 = sim.physics().kernel.support2;
    for (int s = 0; s < 2; ++s) {
      const PairSet truth = brute_force_pairs(sim.particles(), support2);
      ASSERT_GT(truth.size(), 10 * sim.particles().size()) << a.name;
      EXPECT_EQ(pairs_of(sim), truth) << a.name << (s ? " after 40 steps" : " at t = 0");
      if (s == 0)
        for (int k = 0; k < 40; ++k) sim.step();
    }
  }
}

TEST(Ablations, SameStateAsTheDefaultAfter100Steps) {
  std::vector<std::pair<RunConfig, State>> references;  // runs of the default path, reused
  auto reference = [&](const RunConfig& c) -> const State& {
    for (const auto& [rc, state] : references)
      if (rc.list == c.list && rc.reorder == c.reorder && rc.threads == c.threads && rc.gridder == c.gridder &&
          rc.kgc == c.kgc && rc.precision == c.precision && rc.list_steps == c.list_steps &&
          rc.thread_updates == c.thread_updates)
        return state;
    references.emplace_back(c, run(c));
    return references.back().second;
  };
  for (const Ablation& a : ablations()) {
    const RunConfig c = config_with(a);
    // Gridders hold each cell in increasing index, so the direct loop sums in
    // the same order for all four (test_pair_sets checks gridders agree bit
    // for bit); A and C add test time only.
    if (c.pair_loop == PairLoopKind::direct && (c.gridder == GridderKind::A || c.gridder == GridderKind::C)) continue;
    const State s = run(c);
    const State& ref = reference(reference_of(c));
    // bitwise: the same arithmetic; otherwise only the order of the sums differs
    if (a.bitwise) expect_same_bits(s, ref, a.name);
    else if (c.precision == Precision::mixed) expect_float_roundoff_apart(s, ref, a.name);
    else expect_roundoff_apart(s, ref, a.name);
  }
}

TEST(Ablations, ExtraLoopResultMatchesAnIndependentSum) {
  RunConfig c = small_dam_break_config(kParticles);
  c.extra_loops = 2;
  Simulation sim(c);
  for (int s = 0; s < 30; ++s) sim.step();  // a developed, non-lattice state
  EXPECT_EQ(sim.neighbour_stats().extra_loop_passes, 60u);
  EXPECT_GT(sim.neighbour_stats().extra_loop_checksum, 0.0);
  sim.build_neighbours();
  const double pass = sim.extra_loop_pass();
  // Independently: trace M_a = -sum_b V_b F(r_ab) r_ab^2 over the brute-force
  // pairs, both particles of a pair (docs/PHYSICS.md, KGC).
  const ParticleSet& ps = sim.particles();
  std::vector<std::size_t> at(ps.size());
  for (std::size_t i = 0; i < ps.size(); ++i) at[ps.id[i]] = i;
  const CubicSpline& k = sim.physics().kernel;
  double expected = 0;
  for (const auto& [ida, idb] : brute_force_pairs(ps, k.support2)) {
    const std::size_t a = at[ida], b = at[idb];
    const double dx = ps.x[a] - ps.x[b], dy = ps.y[a] - ps.y[b], dz = ps.z[a] - ps.z[b];
    const double r2 = dx * dx + dy * dy + dz * dz, r = std::sqrt(r2);
    const double f = k.dwdr_of_q(r * k.inv_h) / r;
    expected += -f * r2 * (ps.mass[b] / ps.rho[b] + ps.mass[a] / ps.rho[a]);
  }
  EXPECT_NEAR(pass, expected, 1e-12 * std::fabs(expected));
  // Interior particles have M_a close to I: the trace sum is about 3 per fluid particle.
  EXPECT_GT(pass, 1.0 * static_cast<double>(sim.case_info().n_fluid));
}

TEST(Ablations, BadCombinationsAreNamed) {
  auto message = [](RunConfig c) {
    try {
      Simulation sim(c);
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  RunConfig c = small_dam_break_config(kParticles);
  c.pair_loop = PairLoopKind::direct;
  c.list = ListKind::vlx;
  EXPECT_NE(message(c).find("pair_loop = direct applies to the cell-linked list"), std::string::npos) << message(c);
  c.list = ListKind::cll;
  c.skip_boundary_pairs = true;
  EXPECT_NE(message(c).find("skip_boundary_pairs = true needs pair_loop = gather"), std::string::npos) << message(c);
  c.pair_loop = PairLoopKind::masked;
  EXPECT_NE(message(c).find("skip_boundary_pairs = true needs pair_loop = gather"), std::string::npos) << message(c);
  c.list = ListKind::vlc;
  EXPECT_NE(message(c).find("skip_boundary_pairs = true needs pair_loop = gather"), std::string::npos) << message(c);
  c.skip_boundary_pairs = false;
  EXPECT_EQ(message(c), "");  // masked is a Verlet list's loop too
}
