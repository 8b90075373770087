#pragma once
// Simulation: one of each part (particle grid, pair source, pair kernel,
// integrator) chosen at run time from a RunConfig, stepping the case and timing
// the three phases of the paper's Table I on every step.
#include <cstdint>
#include <memory>
#include <vector>

#include "sphnl/case.hpp"
#include "sphnl/config.hpp"
#include "sphnl/neighbours/cell_linked_list.hpp"
#include "sphnl/neighbours/pair_counts.hpp"
#include "sphnl/neighbours/particle_grid.hpp"
#include "sphnl/pair_kernel.hpp"
#include "sphnl/physics.hpp"

namespace sphnl {

/// Wall seconds spent in each phase of Table I, summed over steps.
struct PhaseTimes {
  double neighbour_list = 0;  // cells division, particles in cells, reordering, Verlet list builds
  double force = 0;           // pair loops (KGC pre-pass included)
  double update = 0;          // time step, integration, equation of state
  double total() const { return neighbour_list + force + update; }
};

/// Counters of the neighbour search, summed over steps.
struct NeighbourStats {
  std::uint64_t builds = 0;          // grid/list builds (CLL: one per step)
  std::uint64_t candidates = 0;      // candidate pairs tested in the main loop
  std::uint64_t interactions = 0;    // pairs evaluated in the main loop
  std::uint64_t max_steps_per_list = 0;
};

class Simulation {
 public:
  /// The dam break of paper §2.2 at the size the config asks for.
  explicit Simulation(const RunConfig& config);
  /// Any case (tests: tanks, blobs, single particles).
  Simulation(const RunConfig& config, Case c, const PhysicsParams& phys);

  /// Advances one time step.
  void step();

  const RunConfig& config() const { return config_; }
  const PhysicsParams& physics() const { return phys_; }
  const ParticleSet& particles() const { return ps_; }
  ParticleSet& particles() { return ps_; }
  const Case& case_info() const { return case_; }
  double time() const { return time_; }
  double last_dt() const { return dt_; }
  long steps_done() const { return steps_; }
  std::size_t lost() const { return lost_; }
  const PhaseTimes& phase_times() const { return times_; }
  const NeighbourStats& neighbour_stats() const { return stats_; }
  /// Bytes of the neighbour structures (gridding, ordering, reordering, lists).
  std::size_t neighbour_bytes() const;
  double total_mass() const;
  /// Sum of m v over fluid particles.
  std::array<double, 3> momentum() const;
  /// Largest |v| over fluid particles (after the last step).
  double max_speed() const { return max_speed_; }

  /// Runs the pair source of the config with one op per thread (the one
  /// run-time dispatch per pass); public for tests of pair sources.
  template <class Op>
  PairCounts for_each_pair(std::vector<Op>& ops);
  /// Rebuilds the neighbour structures for the current positions (phase 1).
  void build_neighbours();

 private:
  void init();
  void compute_forces();
  void update(double dt);
  double time_step() const;

  RunConfig config_;
  PhysicsParams phys_;
  Case case_;
  ParticleSet& ps_;
  std::unique_ptr<ParticleGrid> grid_;
  CellLinkedList cll_;
  std::vector<ForceOp<false>> force_ops_;
  std::vector<ForceOp<true>> force_ops_kgc_;
  PhaseTimes times_;
  NeighbourStats stats_;
  double time_ = 0, dt_ = 0, max_speed_ = 0, max_mu_ = 0;
  long steps_ = 0;
  std::size_t lost_ = 0;
};

template <class Op>
PairCounts Simulation::for_each_pair(std::vector<Op>& ops) {
  switch (config_.list) {
    case ListKind::cll: return cll_.for_each_pair(*grid_, ps_, ops, phys_.kernel.support2);
    default: break;
  }
  throw ConfigError("list kind not implemented");
}

}  // namespace sphnl
