#pragma once
// Distributed runs against the serial one: the scenarios the tests run with P
// ranks, either as threads (ThreadCommunicator, test_distributed.cpp: always)
// or as MPI processes (tests/mpi/test_mpi_ranks.cpp under mpirun: when MPI is
// built). Each returns what rank 0 gathered, so one comparison serves both.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "sphnl/parallel/gather_particles.hpp"
#include "sphnl/parallel/thread_communicator.hpp"
#include "sphnl/simulation.hpp"
#include "support/dam_break.hpp"

namespace sphnl::test {

struct Scenario {
  RunConfig config = small_dam_break_config(3000);
  long steps = 50;
  /// The fluid pushed along +x at 1 m/s (particles cross rank boundaries) and
  /// the top layer of the water thrown out through the open top of the tank
  /// (particles leave the domain).
  bool push_out = false;
  /// Another case than the dam break (its PhysicsParams through the argument).
  std::function<Case(PhysicsParams&)> make_case;
};

/// The small dam break with `list` (n_s = 7 for Verlet lists), `order` and `gridder`.
inline Scenario scenario_with(ListKind list, CellOrderKind order = CellOrderKind::sort_x,
                              GridderKind gridder = GridderKind::B) {
  Scenario sc;
  sc.config.list = list;
  sc.config.list_steps = list == ListKind::cll ? 1 : 7;
  sc.config.cell_order = order;
  sc.config.gridder = gridder;
  return sc;
}

/// What a run ends with, at rank 0 (the other ranks' particles empty).
struct Outcome {
  ParticleSet particles;  // every rank's, in id order
  std::size_t lost = 0;
  double mass = 0, initial_mass = 0;
  std::uint64_t builds = 0;
  double extra_loop_checksum = 0;  // extra_loops: the trace sum of M_a, over every rank's owned particles
  // over ranks (distributed runs only)
  double min_fluid_owned = 0;     // fewest fluid particles a rank owned at the start
  double migrated = 0;            // particles that changed rank
  double remote_rebuilds = 0;     // VL_X rebuilds a rank took because another rank's particles moved
  bool builds_equal = true;       // every rank built as often as rank 0
  double interaction_imbalance = 0;  // pairs the busiest rank evaluated over the mean, minus one
};

inline Case scenario_case(const Scenario& sc, PhysicsParams& phys) {
  if (sc.make_case) return sc.make_case(phys);
  Simulation base(sc.config);
  phys = base.physics();
  Case c = base.case_info();
  if (sc.push_out) {
    ParticleSet& ps = c.particles;
    const double top = c.domain.hi[2];
    int thrown = 0;
    for (std::size_t i = 0; i < ps.size(); ++i) {
      if (ps.type[i] != ParticleType::fluid) continue;
      ps.vx[i] += 1.0;
      if (ps.z[i] > 0.27 && thrown < 20) {  // a few from the surface, lifted near the top and thrown up
        ps.z[i] = top - 0.004;
        ps.vz[i] = 2.0;
        ++thrown;
      }
      ps.vx_prev[i] = ps.vx[i];
      ps.vz_prev[i] = ps.vz[i];
    }
  }
  return c;
}

/// One rank's run (comm null: serial).
inline Outcome run_scenario(const Scenario& sc, Communicator* comm) {
  PhysicsParams phys;
  Case c = scenario_case(sc, phys);
  Simulation sim(sc.config, std::move(c), phys, comm);
  Outcome o;
  o.initial_mass = sim.total_mass();
  double fluid_owned = 0;
  for (std::size_t i = 0; i < sim.owned(); ++i) fluid_owned += sim.particles().type[i] == ParticleType::fluid;
  for (long s = 0; s < sc.steps; ++s) sim.step();
  o.mass = sim.total_mass();
  o.lost = sim.lost();
  o.builds = sim.neighbour_stats().builds;
  o.extra_loop_checksum = sim.neighbour_stats().extra_loop_checksum;
  if (!comm) {
    o.particles = sim.particles();
    return o;
  }
  const DomainExchange& d = *sim.domain();
  o.particles = gather_particles(*comm, sim.particles(), sim.owned());
  o.min_fluid_owned = -comm->max(-fluid_owned);
  o.migrated = comm->sum(static_cast<double>(d.migrated()));
  o.remote_rebuilds = comm->sum(static_cast<double>(d.remote_rebuilds()));
  const double b = static_cast<double>(o.builds);
  o.builds_equal = comm->max(b) == -comm->max(-b);
  const double pairs = static_cast<double>(sim.neighbour_stats().interactions);
  o.interaction_imbalance = comm->max(pairs) / (comm->sum(pairs) / comm->size()) - 1.0;
  return o;
}

/// P ranks as threads of this process; the outcome of rank 0.
inline Outcome run_threads(const Scenario& sc, int ranks) {
  auto comms = ThreadCommunicator::make_group(ranks);
  std::vector<Outcome> outcomes(ranks);
  std::vector<std::exception_ptr> errors(ranks);
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r)
    threads.emplace_back([&, r] {
      try {
        outcomes[r] = run_scenario(sc, comms[r].get());
      } catch (...) {
        errors[r] = std::current_exception();
      }
    });
  for (auto& t : threads) t.join();
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
  return outcomes[0];
}

/// The same particles (ids, types), the same total mass, the same lost count,
/// positions within `tol` m.
inline void expect_same_run(const Outcome& serial, const Outcome& dist, double tol = 1e-8) {
  const ParticleSet& a = serial.particles;
  const ParticleSet& b = dist.particles;
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(serial.lost, dist.lost);
  EXPECT_EQ(serial.mass, dist.mass);  // summed in id order on both sides: the same bits
  EXPECT_EQ(serial.initial_mass, dist.initial_mass);
  std::vector<std::size_t> where(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) where[a.id[i]] = i;
  double worst = 0;
  std::size_t type_mismatch = 0;
  for (std::size_t k = 0; k < b.size(); ++k) {
    const std::size_t i = where[b.id[k]];
    type_mismatch += a.type[i] != b.type[k];
    worst = std::max({worst, std::abs(a.x[i] - b.x[k]), std::abs(a.y[i] - b.y[k]), std::abs(a.z[i] - b.z[k])});
  }
  EXPECT_EQ(type_mismatch, 0u);
  EXPECT_LE(worst, tol) << "largest position difference to the serial run";
}

}  // namespace sphnl::test
